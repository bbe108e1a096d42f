"""Standard manoeuvre indices of a track, by the ITTC and IMO definitions: zigzag overshoots from
the check heading, initial turning time, time to check yaw and period; turning-circle advance,
transfer, tactical diameter, steady turning diameter and speed loss; the distance to turn 10 deg
with the first rudder order (IMO's initial turning ability).

Sources: ITTC Recommended Procedure 7.5-04-02-01 (2017), "Full Scale Manoeuvring Trials", Sec.
2.2.1 (turning circle) and 2.2.2 (zigzag); IMO Resolution MSC.137(76), "Standards for ship
manoeuvrability", Sec. 4.2, and MSC/Circ.1053 (explanatory notes).

Pure functions over arrays of a run (time, position, heading, rudder): the measured run and every
prediction of it are reduced to the same indices by the same code. The rudder *orders* (executes)
are read from the rudder angle: the first execute is the rudder leaving its approach angle, every
later one the rudder leaving its hold; the heading at an order is the check heading the standard
measures an overshoot from (with a finite rudder rate the ship turns on while the rudder moves, so
measuring from the heading at which the counter-rudder passes some angle understates it).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import cumulative_trapezoid

__all__ = [
    "INDICES",
    "INITIAL_TURN_DEG",
    "ZIGZAG_TIMING",
    "index_keys",
    "manoeuvre_indices",
    "pull_out_rates",
    "rudder_orders",
    "steady_yaw_rates",
]


def _rudder_holds(t, delta, threshold: float, min_hold_s: float):
    """Runs of the rudder beyond ``threshold`` (rad) on one side, each (side, i_start, i_end, peak
    |delta|), with runs shorter than ``min_hold_s`` dropped (a blip of counter-rudder is not a
    reversal) and neighbouring runs on the same side merged."""
    side = np.where(delta > threshold, 1, np.where(delta < -threshold, -1, 0))
    edge = np.flatnonzero(np.diff(side) != 0) + 1
    starts = np.r_[0, edge]
    ends = np.r_[edge - 1, side.size - 1]
    runs = []
    for i, j in zip(starts, ends):
        if side[i] == 0 or not (t[j] - t[i] >= min_hold_s or (j == side.size - 1 and not runs)):
            continue
        peak = float(np.max(np.abs(delta[i : j + 1])))
        if runs and runs[-1][0] == side[i]:
            s0, a0, _, p0 = runs[-1]
            runs[-1] = (s0, a0, int(j), max(p0, peak))
        else:
            runs.append((int(side[i]), int(i), int(j), peak))
    return runs


#: The heading change (deg) of IMO's initial turning ability: the distance travelled with the first
#: rudder order until the heading has changed by this much (MSC.137(76) Sec. 5.3.2).
INITIAL_TURN_DEG = 10.0

#: The indices of each manoeuvre kind that a model predicts from the recorded rudder (what is
#: predicted, banded and calibrated). The zigzag's ``initial_turning_time_s`` and ``period_s`` are
#: reported for the measured run but not here: they are times between rudder executes, which an
#: open-loop prediction from the recorded rudder inherits from the record (only a closed-loop
#: simulation, reversing at the check heading, predicts them). Every other key of
#: :func:`manoeuvre_indices`' result describes the run (``kind``, ``reason``, execute times).
INDICES = {
    "turning": ("advance_m", "transfer_m", "tactical_diameter_m", "steady_turning_diameter_m", "speed_loss"),
    "zigzag": ("first_overshoot_deg", "second_overshoot_deg", "time_to_check_yaw_s"),
}
#: The timing indices of a zigzag: set by the rudder record (see :data:`INDICES`).
ZIGZAG_TIMING = ("initial_turning_time_s", "period_s")
#: The speed loss of a turn needs a steady approach: at least this many seconds before the execute,
#: over which the speed's 10-90 % spread is at most this fraction of its median.
APPROACH_MIN_S = 5.0
APPROACH_SPREAD = 0.1
#: A rudder hold is a run beyond this angle (rad) on one side lasting at least HOLD_MIN_S.
HOLD_ANGLE = math.radians(3.0)
HOLD_MIN_S = 2.0
#: The rudder has left its hold (or its approach angle) once it is further than this from it (rad),
#: or four times the rudder signal's noise sd when that is larger.
ORDER_TOLERANCE = math.radians(0.5)


def index_keys(indices: dict) -> list:
    """The index keys of a :func:`manoeuvre_indices` result present in it.

    Parameters
    ----------
    indices : dict
        A :func:`manoeuvre_indices` result.

    Returns
    -------
    list of str
        The keys of :data:`INDICES` for its kind present in it (none for ``"other"``).
    """
    return [k for k in INDICES.get(indices.get("kind"), ()) if k in indices]


def _noise_sd(x) -> float:
    """Robust sd of a signal's sample-to-sample noise (1.4826 MAD of its differences / sqrt 2)."""
    d = np.diff(np.asarray(x, float))
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0)) if d.size > 2 else 0.0


def _left(t, delta, i_from: int, i_to: int, value: float, tol: float) -> int:
    """The sample at which ``delta`` leaves ``value`` within ``[i_from, i_to]``: the last one
    within ``tol`` of it, moved back to where the ramp that follows extrapolates to ``value``
    (a steering gear of finite rate takes ``tol / rate`` to get past ``tol``; the order was given
    where it started to move)."""
    dev = np.abs(delta[i_from : i_to + 1] - value)
    near = np.flatnonzero(dev <= tol)
    if not near.size:
        return i_from
    j = int(near[-1])
    if j + 2 >= dev.size:
        return i_from + j
    k = j + 1 + int(np.argmax(dev[j + 1 :] >= 3.0 * tol))  # a point well on the ramp
    if k <= j + 1 or dev[k] <= dev[j + 1]:
        return i_from + j
    tt = t[i_from : i_to + 1]
    rate = (dev[k] - dev[j + 1]) / (tt[k] - tt[j + 1])
    start = tt[j + 1] - dev[j + 1] / rate
    back = int(np.searchsorted(tt, start + 1e-9 * max(1.0, abs(start)), side="right")) - 1
    return i_from + int(np.clip(back, 0, j))


def rudder_orders(t, delta) -> dict:
    """The rudder orders (executes) of a run, read from its rudder angle.

    Parameters
    ----------
    t : (n,) array
        Time (s).
    delta : (n,) array
        Rudder angle (rad).

    Returns
    -------
    dict
        ``holds``: the rudder holds (side, first index, last index, peak |delta|): runs beyond
        :data:`HOLD_ANGLE` on one side lasting :data:`HOLD_MIN_S`; ``executes``: the sample
        index of each order: the first where the rudder leaves its approach angle before the
        first hold, then where it leaves each hold that another hold follows (ITTC 7.5-04-02-01
        Sec. 2.2.2: first, second, third ... execute). Empty lists without a hold.
    """
    t, delta = np.asarray(t, float), np.asarray(delta, float)
    holds = _rudder_holds(t, delta, HOLD_ANGLE, HOLD_MIN_S)
    if not holds:
        return {"holds": [], "executes": []}
    first = holds[0][1]
    approach = float(np.median(delta[: first + 1])) if first > 0 else float(delta[0])
    tol = max(ORDER_TOLERANCE, 4.0 * _noise_sd(delta[: first + 1]))
    executes = [_left(t, delta, 0, first, approach, tol) if first > 0 else 0]
    for (side, a, b, peak), nxt in zip(holds[:-1], holds[1:]):
        # the held angle is the hold's peak (a hold can be shorter than the ramps into it); the
        # noise sd of the signal near it widens the tolerance around it
        core = delta[a : b + 1][side * delta[a : b + 1] >= 0.8 * peak]
        tol = max(ORDER_TOLERANCE, 4.0 * _noise_sd(core))
        executes.append(_left(t, delta, a, nxt[1], side * peak, tol))
    return {"holds": holds, "executes": executes}


def _speed(t, x, y) -> np.ndarray:
    """(n,) speed over ground (m/s) from positions, centred differences over about 1 s."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    k = max(1, int(round(0.5 / dt)))
    i = np.arange(t.size)
    lo, hi = np.clip(i - k, 0, t.size - 1), np.clip(i + k, 0, t.size - 1)
    span = np.where(hi > lo, t[hi] - t[lo], np.nan)
    return np.hypot(x[hi] - x[lo], y[hi] - y[lo]) / span


def _circle_diameter(x, y) -> float:
    """Diameter (m) of the least-squares circle through points (algebraic fit: Kasa 1976, IEEE
    Trans. Instrum. Meas. 25(1))."""
    A = np.column_stack([x, y, np.ones_like(x)])
    b = x * x + y * y
    (cx2, cy2, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    r2 = c + (cx2 / 2) ** 2 + (cy2 / 2) ** 2
    return float(2.0 * math.sqrt(r2)) if r2 > 0 else float("nan")


def _crossing(h, a: int, b: int, ang: float):
    """Fractional index in ``[a, b]`` where ``|h|`` first reaches ``ang`` (linear between
    samples), or None."""
    k = np.flatnonzero(np.abs(h[a : b + 1]) >= ang)
    if not k.size:
        return None
    j = a + int(k[0])
    if j == a:
        return float(j)
    h0, h1 = abs(h[j - 1]), abs(h[j])
    return j - 1 + (ang - h0) / (h1 - h0) if h1 != h0 else float(j)


def _at(v, f: float) -> float:
    """``v`` at a fractional index (linear)."""
    j = int(math.floor(f))
    w = f - j
    return float(v[j]) if w == 0 or j + 1 >= v.size else float((1 - w) * v[j] + w * v[j + 1])


def _approach_speed(t, speed, i0: int) -> float:
    """The steady approach speed before the execute ``i0``: the median speed over the 10 s before
    it, or NaN when there are fewer than :data:`APPROACH_MIN_S` seconds of approach or the speed
    varies there by more than :data:`APPROACH_SPREAD` of it (a ship still accelerating, as the
    Esso Osaka turns that start from rest: a speed loss then means nothing)."""
    k = max(0, int(np.searchsorted(t, t[i0] - 10.0)))
    v = speed[k : i0 + 1]
    v = v[np.isfinite(v)]
    if t[i0] - t[k] < APPROACH_MIN_S or v.size < 3:
        return float("nan")
    med = float(np.median(v))
    lo, hi = np.percentile(v, [10, 90])
    return med if med > 0 and (hi - lo) <= APPROACH_SPREAD * med else float("nan")


def _first_order(t, x, y, h, i0: int, hold, end: int) -> dict:
    """What the first rudder order did, for a turn and a zigzag alike: the rudder angle held
    (``rudder_deg``, signed, + port), the speed over ground at the execute (``execute_speed_m_s``:
    the median over the 10 s before it to 1 s after, the test speed V of IMO MSC.137(76) Sec.
    4.2.1 read from the run) and the distance travelled along the track from the execute until
    the heading has changed by :data:`INITIAL_TURN_DEG` with the first order still in force, i.e.
    by sample ``end`` (the end of a turn's hold; one sample past a zigzag's second execute, the
    order to reverse being given where the heading got there) (``initial_turning_distance_m``,
    MSC.137(76) Sec. 5.3.2; MSC/Circ.1053 reads it from the 10/10 zigzag; NaN when the heading
    does not get there)."""
    side, _, _, peak = hold
    speed = _speed(t, x, y)
    near = (t >= t[i0] - 10.0) & (t <= t[i0] + 1.0) & np.isfinite(speed)
    f = _crossing(h, i0, end, math.radians(INITIAL_TURN_DEG))
    # the path length as the integral of the speed (centred differences over about 1 s), which
    # position noise does not inflate as a sum of sample-to-sample steps would
    path = cumulative_trapezoid(np.nan_to_num(speed), t, initial=0.0)
    return {
        "rudder_deg": float(np.degrees(side * peak)),
        "execute_speed_m_s": float(np.median(speed[near])) if near.any() else float("nan"),
        "initial_turning_distance_m": _at(path, f) - float(path[i0]) if f is not None else float("nan"),
    }


def _turning(t, x, y, psi, h, i0: int, hold) -> dict:
    """The turning-circle indices of one rudder hold from the execute ``i0`` (ITTC
    7.5-04-02-01 Sec. 2.2.1, IMO MSC.137(76) Sec. 2.3-2.4)."""
    _, a, b, _ = hold
    c, s = math.cos(psi[i0]), math.sin(psi[i0])
    along = c * (x - x[i0]) + s * (y - y[i0])
    normal = -s * (x - x[i0]) + c * (y - y[i0])
    out = {}
    f90, f180 = _crossing(h, i0, b, math.pi / 2), _crossing(h, i0, b, math.pi)
    out["advance_m"] = _at(along, f90) if f90 is not None else float("nan")
    out["transfer_m"] = abs(_at(normal, f90)) if f90 is not None else float("nan")
    out["tactical_diameter_m"] = abs(_at(normal, f180)) if f180 is not None else float("nan")
    # steady turning: from 180 deg of heading change to the end of the hold, at least 90 deg of arc
    steady = np.flatnonzero(np.abs(h[a : b + 1]) >= math.pi) + a
    speed = _speed(t, x, y)
    u0 = _approach_speed(t, speed, i0)
    if steady.size and abs(h[steady[-1]] - h[steady[0]]) >= math.pi / 2:
        out["steady_turning_diameter_m"] = _circle_diameter(x[steady], y[steady])
        out["speed_loss"] = float(1.0 - np.nanmedian(speed[steady]) / u0) if u0 > 0 else float("nan")
    else:
        out["steady_turning_diameter_m"] = float("nan")
        out["speed_loss"] = float("nan")
    return out


def _zigzag(t, h, executes) -> dict:
    """The zigzag indices from the executes (ITTC 7.5-04-02-01 Sec. 2.2.2, IMO MSC.137(76) Sec.
    2.4): overshoots measured from the heading at the 2nd and 3rd executes."""
    out = {"check_heading_deg": [float(np.degrees(h[m])) for m in executes[1:]]}
    orders = executes[1:]
    peak1 = None
    for name, k in (("first_overshoot_deg", 0), ("second_overshoot_deg", 1)):
        if k >= len(orders):
            out[name] = float("nan")
            continue
        m = orders[k]
        prev = executes[k]
        going = np.sign(h[m] - h[prev]) or 1.0  # the way the heading turned towards this check heading
        end = orders[k + 1] if k + 1 < len(orders) else h.size - 1
        seg = going * (h[m : end + 1] - h[m])
        j = int(np.argmax(seg))
        out[name] = float(np.degrees(max(seg[j], 0.0)))
        if k == 0:
            peak1 = m + j
    out["initial_turning_time_s"] = float(t[orders[0]] - t[executes[0]]) if orders else float("nan")
    out["time_to_check_yaw_s"] = float(t[peak1] - t[orders[0]]) if peak1 is not None else float("nan")
    out["period_s"] = float(t[orders[2]] - t[orders[0]]) if len(orders) >= 3 else float("nan")
    return out


def manoeuvre_indices(t, x, y, psi, delta) -> dict:
    """Standard indices of a turning circle or a zigzag from a track, after deciding which
    manoeuvre the run is (module docstring for the sources).

    The rudder is read as holds and orders (:func:`rudder_orders`); the first execute is the
    rudder leaving its approach angle, and the heading change is measured from the heading there
    (the original course).

    * **turning**: one hold (the rudder never reversed) during which the heading changes by at
      least 90 deg: ``advance_m`` (distance along the original course from the execute to 90 deg
      of heading change), ``transfer_m`` (normal to it, at 90 deg), ``tactical_diameter_m``
      (normal distance at 180 deg), each interpolated between samples; ``steady_turning_diameter_m``
      (least-squares circle through the track from 180 deg of heading change to the end of the
      hold, given at least 90 deg of arc) and ``speed_loss`` (1 - steady turning speed /
      approach speed, both from the positions; approach: the 10 s before the execute, NaN
      without a steady approach). NaN where the heading does not get there before the rudder
      returns;
    * **zigzag**: at least two reversals between holds of similar size (each within a factor of
      two of the first), the heading oscillating about the original course (never 90 deg away):
      ``first_overshoot_deg`` and ``second_overshoot_deg`` (the heading beyond the check heading,
      i.e. the heading at the 2nd and 3rd executes), ``initial_turning_time_s`` (1st to 2nd
      execute), ``time_to_check_yaw_s`` (2nd execute to the first heading extreme) and
      ``period_s`` (2nd to 4th execute: one cycle, NaN with fewer executes); also
      ``check_heading_deg`` (the heading change at each later execute) and ``executes_t_s``
      (every execute);
    * both: ``rudder_deg`` (the first hold's rudder angle, + port), ``execute_speed_m_s`` (the
      speed over ground at the first execute: the test speed) and ``initial_turning_distance_m``
      (the distance travelled from the first execute until the heading has changed by
      :data:`INITIAL_TURN_DEG` with the first rudder order still held, IMO MSC.137(76) Sec.
      5.3.2; NaN when it does not get there). :mod:`bayesid.estimation.imo` reads the IMO
      criteria from these;
    * otherwise ``"other"`` with the ``reason``, and no index.

    Parameters
    ----------
    t : (n,) array
        Time (s).
    x : (n,) array
        North position (m).
    y : (n,) array
        East position (m).
    psi : (n,) array
        Heading (rad, any wrap).
    delta : (n,) array
        Rudder angle (rad).

    Returns
    -------
    dict
        ``kind`` (``"turning"``, ``"zigzag"``, ``"other"``), ``execute_t_s`` (the first execute)
        and the indices of :data:`INDICES` for the kind (a zigzag also :data:`ZIGZAG_TIMING`)
        with the first order's ``rudder_deg``, ``execute_speed_m_s`` and
        ``initial_turning_distance_m``, or ``reason``.
    """
    t, x, y, delta = (np.asarray(a, float) for a in (t, x, y, delta))
    psi = np.unwrap(np.asarray(psi, float))
    orders = rudder_orders(t, delta)
    holds, executes = orders["holds"], orders["executes"]
    if not holds:
        return {"kind": "other", "reason": "the rudder is never held beyond 3 deg for 2 s"}
    i0 = executes[0]
    out = {"execute_t_s": float(t[i0])}
    h = psi - psi[i0]
    if len(holds) == 1:
        _, a, b, _ = holds[0]
        turned = float(np.degrees(np.max(np.abs(h[a : b + 1]))))
        if turned < 90.0:
            return dict(
                out,
                kind="other",
                reason=f"one rudder hold, but the heading changed only {turned:.0f} deg "
                "while it was held (a turning circle needs 90)",
            )
        return dict(
            out,
            kind="turning",
            **_turning(t, x, y, psi, h, i0, holds[0]),
            **_first_order(t, x, y, h, i0, holds[0], holds[0][2]),
        )
    first = holds[0][3]
    similar = all(0.5 * first <= p <= 2.0 * first for _, _, _, p in holds)
    span = float(np.degrees(np.max(np.abs(h[i0:]))))
    if len(holds) < 3 or not similar or span >= 90.0:
        why = (
            f"the rudder reversed {len(holds) - 1} time(s)"
            + (", between holds of different sizes" if not similar else "")
            + f", and the heading moved up to {span:.0f} deg from the approach heading"
        )
        return dict(
            out,
            kind="other",
            reason=why + " (a zigzag needs 2 reversals of one rudder angle with the "
            "heading within 90 deg; a turning circle one hold)",
        )
    out["executes_t_s"] = [float(t[m]) for m in executes]
    end = min(holds[0][2], executes[1] + 1)
    return dict(out, kind="zigzag", **_zigzag(t, h, executes), **_first_order(t, x, y, h, i0, holds[0], end))


def _constant_rudder(t, delta, min_hold_s: float, tol: float) -> list:
    """(i_start, i_end, mean angle) of each run of the rudder within ``tol`` (rad) of its first
    value lasting at least ``min_hold_s``."""
    runs, i = [], 0
    while i < delta.size:
        j = i
        while j + 1 < delta.size and abs(delta[j + 1] - delta[i]) <= tol:
            j += 1
        if t[j] - t[i] >= min_hold_s:
            runs.append((i, j, float(np.mean(delta[i : j + 1]))))
        i = j + 1
    return runs


def steady_yaw_rates(t, delta, r, *, min_hold_s: float = 10.0, settled: float = 1.0 / 3.0) -> list:
    """The steady yaw rate at each rudder angle of a spiral test (ITTC 7.5-04-02-01 Sec. 2.2.4):
    the mean yaw rate over the last ``settled`` part of each hold of the rudder.

    Parameters
    ----------
    t : (n,) array
        Time (s).
    delta : (n,) array
        Rudder angle (rad).
    r : (n,) array
        Yaw rate (rad/s).
    min_hold_s : float, default 10.0
        Shortest hold of one rudder angle counted (s).
    settled : float, default 1/3
        The part of each hold, at its end, averaged.

    Returns
    -------
    list of dict
        Per hold in time order: ``rudder_deg``, ``t_start_s``, ``t_end_s``, ``yaw_rate_deg_s``
        (the mean) and ``drift_deg_s`` (its change over the part averaged: near 0 when steady).
    """
    t, delta, r = (np.asarray(a, float) for a in (t, delta, r))
    out = []
    for i, j, angle in _constant_rudder(t, delta, min_hold_s, ORDER_TOLERANCE):
        k = int(np.searchsorted(t, t[j] - settled * (t[j] - t[i])))
        seg = r[k : j + 1]
        out.append(
            {
                "rudder_deg": float(np.degrees(angle)),
                "t_start_s": float(t[i]),
                "t_end_s": float(t[j]),
                "yaw_rate_deg_s": float(np.degrees(np.mean(seg))),
                "drift_deg_s": float(np.degrees(seg[-1] - seg[0])),
            }
        )
    return out


def pull_out_rates(t, delta, r) -> dict:
    """The yaw rates of a pull-out test (ITTC 7.5-04-02-01 Sec. 2.2.6): at the release of the
    rudder and at the end of the run.

    Parameters
    ----------
    t : (n,) array
        Time (s).
    delta : (n,) array
        Rudder angle (rad).
    r : (n,) array
        Yaw rate (rad/s).

    Returns
    -------
    dict
        ``release_t_s`` (the rudder leaving its last hold), ``yaw_rate_at_release_deg_s`` (mean
        over the 5 s before), ``residual_yaw_rate_deg_s`` (mean over the last 5 s: near 0 for a
        directionally stable ship, the width of its spiral loop otherwise) and
        ``residual_fraction`` (their ratio); empty without a rudder hold released before the end.
    """
    t, delta, r = (np.asarray(a, float) for a in (t, delta, r))
    holds = _rudder_holds(t, delta, HOLD_ANGLE, HOLD_MIN_S)
    if not holds or holds[-1][2] >= t.size - 1:
        return {}
    j = holds[-1][2] + 1
    before = r[(t >= t[j] - 5.0) & (t < t[j])]
    end = r[t >= t[-1] - 5.0]
    r0, r1 = float(np.mean(before)), float(np.mean(end))
    return {
        "release_t_s": float(t[j]),
        "yaw_rate_at_release_deg_s": math.degrees(r0),
        "residual_yaw_rate_deg_s": math.degrees(r1),
        "residual_fraction": r1 / r0 if r0 else float("nan"),
    }
