"""Standard manoeuvres of a surface ship, simulated with its MMG equations
(:mod:`bayesid.models.ship.dynamics`): turning circle, zigzag (closed loop on the heading), pull-out
and the direct/reverse spiral, from a steady approach at the ship's service (or a given) speed.

Procedures: ITTC Recommended Procedure 7.5-04-02-01 (2017), "Full Scale Manoeuvring Trials", Sec.
2.2.1 (turning circle), 2.2.2 (zigzag), 2.2.4 (spiral: direct, Dieudonne; here run down from one
side to the other and back, so that a loop of an unstable ship shows), 2.2.6 (pull-out). The
indices of the runs are read by :mod:`bayesid.estimation.indices` from the simulated track, as
from a measured one.

Sign convention: the package's rudder is positive to port; a ship going ahead then turns to port
(``r < 0``). A negative rudder angle turns to starboard (and starts a zigzag to starboard).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field

import numba as nb
import numpy as np
from scipy.optimize import brentq

from ...data.track import Track
from ..runs import canonical_kind
from .dynamics import accelerations, forces
from .fileformat import Ship, ShipFileError

#: The keys of a ship file's optional ``[service]`` section: approach speed (m/s, the file's
#: scale), propeller speed (rpm) at it, and the steering gear's rate (deg/s).
SERVICE_KEYS = ("speed", "rpm", "rudder_rate_deg_s")
#: The manoeuvres :func:`simulate_trial` runs (names of :data:`bayesid.models.runs.MANOEUVRE_KINDS`;
#: the aliases of :data:`bayesid.models.runs.KIND_ALIASES`, ``turn`` among them, are accepted).
KINDS = ("turning_circle", "zigzag", "pull_out", "spiral", "straight")
#: Straight approach before the first rudder order, s.
T_EXECUTE = 10.0
#: Default lengths of the runs after the execute, in ship-length times ``L / U``: long enough for
#: 540 deg of a 35 deg turn or four zigzag reversals of a full-form ship (KVLCC2: 60 L/U = 356 s).
RUN_SHIP_LENGTHS = {"turning_circle": 60.0, "zigzag": 60.0, "pull_out": 40.0, "straight": 10.0}
#: Default hold of each spiral step, ship-length times (KVLCC2: 119 s, within 1 % of the steady
#: yaw rate away from the loop).
SPIRAL_HOLD_SHIP_LENGTHS = 20.0
#: The spiral's rudder steps as fractions of the largest angle (20 deg: 20, 15, 10, 5, 3, 1, 0).
SPIRAL_FRACTIONS = (1.0, 0.75, 0.5, 0.25, 0.15, 0.05, 0.0)


def service_condition(ship: Ship) -> dict:
    """The ship file's ``[service]`` section: the approach the standard manoeuvres start from.

    Parameters
    ----------
    ship : Ship
        The ship (its file is read again; a ship built in code has none).

    Returns
    -------
    dict
        The keys of :data:`SERVICE_KEYS` the file gives (speed in m/s, rpm, rudder rate in deg/s);
        empty without a ``[service]`` section.

    Raises
    ------
    ShipFileError
        An unknown key, or a value that is not a positive finite number (naming file and key).
    """
    if not ship.file_path:
        return {}
    with open(ship.file_path, "rb") as fh:
        sec = tomllib.load(fh).get("service", {})
    out = {}
    for k, v in sec.items():
        if k not in SERVICE_KEYS:
            raise ShipFileError(f"{ship.file_path}: [service] unknown key {k!r}; known: {', '.join(SERVICE_KEYS)}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ShipFileError(f"{ship.file_path}: [service] {k} = {v!r} must be a positive finite number")
        out[k] = float(v)
    return out


def _surge_force(prm, u: float, rpm: float) -> float:
    """Surge force (N) going straight ahead at ``u`` (m/s), rudder amidships, propeller ``rpm``."""
    out = np.empty((1, 3))
    forces(
        np.array([[0.0, 0.0, 0.0, u, 0.0, 0.0]]), np.array([[0.0, rpm / 60.0]]), np.zeros((1, 2)), np.zeros(2), prm, out
    )
    return float(out[0, 0])


def propulsion_point(ship: Ship, speed: float | None = None, rpm: float | None = None) -> tuple[float, float]:
    """The straight-ahead equilibrium of the ship's model: the propeller speed that holds a speed
    (the model's self-propulsion point), or the speed a propeller speed settles at.

    Parameters
    ----------
    ship : Ship
        The ship.
    speed : float, optional
        Speed, m/s.
    rpm : float, optional
        Propeller speed, rpm.

    Returns
    -------
    tuple of float
        ``(speed, rpm)``: the one not given solved for (surge force zero); both as given when
        both are given.

    Raises
    ------
    ValueError
        Neither given, or no equilibrium within 0.001-50 m/s (0.06-6000 rpm).
    """
    return equilibrium(ship.params(), speed=speed, rpm=rpm, label=ship.id)


def equilibrium(prm, speed: float | None = None, rpm: float | None = None, label: str = "") -> tuple[float, float]:
    """:func:`propulsion_point` of a kernel parameter vector (a fitted model's row,
    :meth:`~bayesid.models.ship.model.ShipModel.kernel_params`, with its effects' shifts).

    Parameters
    ----------
    prm : ndarray, shape (NP + extra hull terms,)
        Kernel parameters (:meth:`~bayesid.models.ship.fileformat.Ship.params` layout).
    speed, rpm : float, optional
        As :func:`propulsion_point`.
    label : str, optional
        Names the ship in the error.

    Returns
    -------
    tuple of float
        ``(speed, rpm)``, as :func:`propulsion_point`.

    Raises
    ------
    ValueError
        As :func:`propulsion_point`.
    """
    if speed is not None and rpm is not None:
        return float(speed), float(rpm)
    prm = np.asarray(prm, float)
    if speed is not None:
        f = lambda n: _surge_force(prm, speed, n)  # noqa: E731
        lo, hi = 0.06, 6000.0
        what = f"no propeller speed in {lo:g}-{hi:g} rpm holds {speed:g} m/s"
    elif rpm is not None:
        f = lambda u: _surge_force(prm, u, rpm)  # noqa: E731
        lo, hi = 1e-3, 50.0
        what = f"no steady speed in {lo:g}-{hi:g} m/s at {rpm:g} rpm"
    else:
        raise ValueError("give a speed or a propeller speed")
    if not np.sign(f(lo)) * np.sign(f(hi)) < 0:
        raise ValueError(f"{label}: {what} (the model's surge force does not change sign)")
    x = float(brentq(f, lo, hi, xtol=1e-10, rtol=1e-12))
    return (float(speed), x) if speed is not None else (x, float(rpm))


@nb.njit(cache=True)
def _run(s0, prm, dt, rps, order, check, turn_sign, rate, every, states, rudder):
    """RK4 of one run with a rate-limited rudder following ``order`` (rad, per step); with
    ``check > 0`` a zigzag: from the first non-zero order on, the order is reversed each time the
    heading change from the execute heading reaches ``check`` (rad) the way it turns. Samples
    every ``every`` steps into ``states`` (m, 6) and ``rudder`` (m,); returns the last step done
    (``n`` when the run did not diverge).

    The rudder logged at a sample is the one applied over the step that starts there, and the
    angle it is at then: a gear of finite rate applies the angle it has reached and moves on
    towards the order over the step (an order given at a step shows as the rudder leaving its
    angle from that step's sample on, as on a log of a real rudder); an instantaneous rudder is
    at the order from its step on."""
    n = order.size
    s = s0.copy()
    st = np.empty((1, 6))
    u2 = np.empty((1, 2))
    wind = np.zeros((1, 2))
    cur = np.zeros(2)
    acc = np.empty((1, 3))
    ks = np.empty((4, 6))
    delta = 0.0
    cmd = 0.0
    psi0 = s0[2]
    started = False
    for k in range(n):
        if check > 0.0:
            if not started and order[k] != 0.0:
                started = True
                cmd = order[k]
                psi0 = s[2]
            elif started:
                h = s[2] - psi0
                going = turn_sign * math.copysign(1.0, cmd)  # the sign of the heading change cmd makes
                if going * h >= check:
                    cmd = -cmd
        else:
            cmd = order[k]
        if rate > 0.0:
            applied = delta
            delta += min(max(cmd - delta, -rate * dt), rate * dt)
        else:
            delta = cmd
            applied = delta
        if k % every == 0:
            states[k // every] = s
            rudder[k // every] = applied
        u2[0, 0] = applied
        u2[0, 1] = rps
        for stage in range(4):
            a = 0.0 if stage == 0 else (0.5 * dt if stage < 3 else dt)
            for j in range(6):
                st[0, j] = s[j] + a * ks[stage - 1, j] if stage > 0 else s[j]
            accelerations(st, u2, wind, cur, prm, acc)
            c, sn = math.cos(st[0, 2]), math.sin(st[0, 2])
            ks[stage, 0] = st[0, 3] * c - st[0, 4] * sn
            ks[stage, 1] = st[0, 3] * sn + st[0, 4] * c
            ks[stage, 2] = st[0, 5]
            ks[stage, 3] = acc[0, 0]
            ks[stage, 4] = acc[0, 1]
            ks[stage, 5] = acc[0, 2]
        bad = False
        for j in range(6):
            s[j] += dt / 6.0 * (ks[0, j] + 2.0 * ks[1, j] + 2.0 * ks[2, j] + ks[3, j])
            if not math.isfinite(s[j]):
                bad = True
        if bad or abs(s[3]) > 50.0 or abs(s[4]) > 50.0 or abs(s[5]) > 10.0:
            return k
    if n % every == 0:
        states[n // every] = s
        rudder[n // every] = delta
    return n


@dataclass
class Trial:
    """A simulated ship manoeuvre (the result of :func:`simulate_trial`).

    Parameters
    ----------
    track : Track
        The run: ``t``, ``x``, ``y``, ``psi``, ``u``, ``v``, ``r``, ``delta_r`` (the rudder as
        it moved: the angle at each sample time, applied from it on) and ``n`` (rpm);
        ``meta["comments"]`` describe it.
    name : str
        ``turn35``, ``zigzag10_10``, ``pull_out20``, ``spiral20`` style (``m`` for a negative
        angle).
    description : str
        One line on what was run.
    speed : float
        Approach speed, m/s.
    rpm : float
        Propeller speed, rpm.
    parameters : dict
        The settings of the run (angle, check heading, durations, rudder rate, spiral steps).
    """

    track: Track
    name: str
    description: str
    speed: float
    rpm: float
    parameters: dict = field(default_factory=dict)


def spiral_steps(angle_deg: float) -> list[float]:
    """The rudder angles of a direct/reverse spiral, deg: from ``angle_deg`` through zero to
    ``-angle_deg`` and back (:data:`SPIRAL_FRACTIONS`; ITTC 7.5-04-02-01 Sec. 2.2.4).

    Parameters
    ----------
    angle_deg : float
        The largest rudder angle, deg (the sign sets the side the run starts on).

    Returns
    -------
    list of float
        The steps in order (25 of them).
    """
    down = [angle_deg * f for f in SPIRAL_FRACTIONS] + [-angle_deg * f for f in SPIRAL_FRACTIONS[::-1][1:]]
    return down + down[::-1][1:]


@dataclass(frozen=True)
class TrialOptions:
    """How a trial of :func:`simulate_trial` is run and logged.

    Parameters
    ----------
    dt : float, default 0.1
        Integration step, s.
    sample_every : int, default 1
        Steps per output sample.
    duration : float, optional
        Length of the run after the execute, s (not for a spiral); default
        :data:`RUN_SHIP_LENGTHS` ship-length times ``L / speed`` (a pull-out: its hold and as
        long again).
    hold : float, optional
        Pull-out: time at the rudder angle; spiral: time at each step, s; default
        :data:`SPIRAL_HOLD_SHIP_LENGTHS` (spiral) or :data:`RUN_SHIP_LENGTHS` (pull-out) times
        ``L / speed``.
    rudder_rate_deg_s : float, default 0.0
        Steering gear rate, deg/s; 0 moves the rudder at once.
    """

    dt: float = 0.1
    sample_every: int = 1
    duration: float | None = None
    hold: float | None = None
    rudder_rate_deg_s: float = 0.0


def simulate_trial(
    ship: Ship,
    kind: str,
    angle_deg: float,
    *,
    check_deg: float | None = None,
    speed: float,
    rpm: float,
    options: TrialOptions = TrialOptions(),
) -> Trial:
    """Simulate a standard manoeuvre of a ship from a straight approach.

    The run starts going straight at ``speed`` with the propeller at ``rpm`` (constant
    throughout); the first rudder order is given at :data:`T_EXECUTE` s. ``turning_circle``: the rudder
    put to ``angle_deg`` and held. ``zigzag``: to ``angle_deg``, reversed each time the heading
    has changed by ``check_deg`` from the execute heading (closed loop). ``pull_out``: held for
    ``hold`` s, then returned to amidships. ``spiral``: the steps of :func:`spiral_steps`, each
    held ``hold`` s. ``straight``: rudder amidships.

    Parameters
    ----------
    ship : Ship
        The ship.
    kind : {"turning_circle", "zigzag", "pull_out", "spiral", "straight"}
        The manoeuvre (:data:`KINDS`; ``"turn"`` and ``"pull-out"`` are accepted too).
    angle_deg : float
        Rudder angle, deg, + to port (a negative angle turns, or starts a zigzag, to starboard).
    check_deg : float, optional
        Zigzag check heading (heading change that reverses the rudder), deg, positive; default
        ``abs(angle_deg)``.
    speed : float
        Approach speed, m/s.
    rpm : float
        Propeller speed, rpm.
    options : TrialOptions, default TrialOptions()
        Step, logging rate, run length, hold and steering-gear rate.

    Returns
    -------
    Trial
        The run.

    Raises
    ------
    ValueError
        Unknown kind; a non-positive speed, step or check heading; a zero angle for a turn,
        zigzag or pull-out; a run that diverges (naming the time).
    """
    dt, sample_every, duration, hold = options.dt, options.sample_every, options.duration, options.hold
    rudder_rate_deg_s = options.rudder_rate_deg_s
    kind = canonical_kind(kind, KINDS, "ship manoeuvre")
    if not speed > 0 or not dt > 0:
        raise ValueError(f"speed ({speed}) and step ({dt}) must be positive")
    if kind in ("turning_circle", "zigzag", "pull_out", "spiral") and angle_deg == 0:
        raise ValueError(f"a {_WORDS.get(kind, kind)} needs a rudder angle other than 0")
    check_deg = abs(angle_deg) if check_deg is None else float(check_deg)
    if kind == "zigzag" and not check_deg > 0:
        raise ValueError(f"the zigzag's check heading must be positive, not {check_deg:g} deg")
    tl = ship.L / speed
    params = {"angle_deg": angle_deg, "t_execute_s": T_EXECUTE, "rudder_rate_deg_s": rudder_rate_deg_s}
    a = math.radians(angle_deg)
    if kind == "spiral":
        hold = SPIRAL_HOLD_SHIP_LENGTHS * tl if hold is None else hold
        steps = spiral_steps(angle_deg)
        k_exec, k_hold = _whole(T_EXECUTE, dt), _whole(hold, dt)
        order = np.zeros(k_exec + k_hold * len(steps))
        for i, s in enumerate(steps):
            order[k_exec + i * k_hold : k_exec + (i + 1) * k_hold] = math.radians(s)
        params.update(hold_s=k_hold * dt, steps_deg=steps)
        name = _named("spiral", angle_deg)
        desc = f"direct/reverse spiral, rudder {', '.join(f'{s:g}' for s in steps)} deg, each held {k_hold * dt:g} s"
    else:
        if kind == "pull_out":
            hold = RUN_SHIP_LENGTHS["pull_out"] * tl if hold is None else hold
            duration = 2.0 * hold if duration is None else duration
        duration = RUN_SHIP_LENGTHS[kind] * tl if duration is None else duration
        k_exec, n = _whole(T_EXECUTE, dt), _whole(T_EXECUTE + duration, dt)
        order = np.zeros(n)
        if kind in ("turning_circle", "zigzag"):
            order[k_exec:] = a
        elif kind == "pull_out":
            k_off = min(n, k_exec + _whole(hold, dt))
            order[k_exec:k_off] = a
            params["release_t_s"] = k_off * dt
        params["duration_s"] = n * dt
        if kind == "zigzag":
            params["check_deg"] = check_deg
            name = f"zigzag{abs(angle_deg):g}_{check_deg:g}" + ("" if angle_deg > 0 else "_starboard")
            desc = (
                f"zigzag {abs(angle_deg):g}/{check_deg:g}, first to {'port' if angle_deg > 0 else 'starboard'}, "
                f"reversed at {check_deg:g} deg of heading change (closed loop)"
            )
        elif kind == "turning_circle":
            name, desc = _named("turn", angle_deg), f"turning circle, rudder {angle_deg:g} deg"
        elif kind == "pull_out":
            name = _named("pull_out", angle_deg)
            desc = f"pull-out, rudder {angle_deg:g} deg for {params['release_t_s'] - T_EXECUTE:g} s, then amidships"
        else:
            name, desc = "straight", "straight run, rudder amidships"
    every = int(sample_every)
    n = order.size
    m = n // every + 1
    states, rudder = np.full((m, 6), np.nan), np.full(m, np.nan)
    s0 = np.array([0.0, 0.0, 0.0, float(speed), 0.0, 0.0])
    done = _run(
        s0,
        ship.params(),
        float(dt),
        rpm / 60.0,
        order,
        math.radians(check_deg) if kind == "zigzag" else 0.0,
        _turn_sign(ship, speed, rpm),
        math.radians(rudder_rate_deg_s),
        every,
        states,
        rudder,
    )
    if done < n:
        raise ValueError(
            f"{ship.id}: the {name} run diverged at t = {done * dt:g} s (a speed, rudder angle or step "
            "beyond what the model holds?)"
        )
    t = np.arange(m) * every * dt
    S = states[:m]
    track = Track.from_arrays(
        t,
        states={"x": S[:, 0], "y": S[:, 1], "psi": S[:, 2], "u": S[:, 3], "v": S[:, 4], "r": S[:, 5]},
        inputs={"delta_r": rudder[:m], "n": np.full(m, float(rpm))},
        name=name,
    )
    rate = "instantaneous" if rudder_rate_deg_s <= 0 else f"{rudder_rate_deg_s:g} deg/s"
    desc = (
        f"{desc}; approach {speed:.4g} m/s, {rpm:.4g} rpm, execute at {T_EXECUTE:g} s; rudder rate {rate}; dt {dt:g} s"
    )
    return Trial(track, name, desc, float(speed), float(rpm), params)


#: The kinds as words in messages.
_WORDS = {"turning_circle": "turning circle", "pull_out": "pull-out"}


def _whole(seconds: float, dt: float) -> int:
    """Steps of ``dt`` in ``seconds`` (rounded; at least one)."""
    return max(1, int(round(seconds / dt)))


def _named(prefix: str, angle_deg: float) -> str:
    return f"{prefix}{abs(angle_deg):g}" + ("" if angle_deg > 0 else "_starboard")


def _turn_sign(ship: Ship, speed: float, rpm: float) -> float:
    """The sign of the yaw rate a positive (port) rudder gives the ship going ahead: -1 for the
    package's convention (port rudder, heading decreasing), read from the model's yaw moment."""
    out = np.empty((1, 3))
    s = np.array([[0.0, 0.0, 0.0, speed, 0.0, 0.0]])
    forces(s, np.array([[math.radians(10.0), rpm / 60.0]]), np.zeros((1, 2)), np.zeros(2), ship.params(), out)
    n_port = out[0, 2]
    forces(s, np.array([[-math.radians(10.0), rpm / 60.0]]), np.zeros((1, 2)), np.zeros(2), ship.params(), out)
    return 1.0 if n_port > out[0, 2] else -1.0


__all__ = [
    "KINDS",
    "SERVICE_KEYS",
    "Trial",
    "equilibrium",
    "propulsion_point",
    "service_condition",
    "simulate_trial",
    "TrialOptions",
    "spiral_steps",
]
