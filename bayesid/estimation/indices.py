"""Standard manoeuvre indices of a track, by the ITTC and IMO definitions: zigzag overshoots from
the check heading, initial turning time, time to check yaw and period; turning-circle advance,
transfer, tactical diameter, steady turning diameter and speed loss; the distance to turn 10 deg
with the first rudder order (IMO's initial turning ability).

Sources: ITTC Recommended Procedure 7.5-04-02-01 (2017), "Full Scale Manoeuvring Trials", Sec.
2.2.1 (turning circle) and 2.2.2 (zigzag); IMO Resolution MSC.137(76), "Standards for ship
manoeuvrability", Sec. 4.2, and MSC/Circ.1053 (explanatory notes).

Pure functions over arrays of a run (time, position, heading, rudder): the measured run and every
prediction of it are reduced to the same indices by the same code. The rudder *orders* (executes)
are read from the rudder angle: the first execute is the rudder leaving its approach angle (a
turn's: the start of the last ramp into the angle it holds, after any course keeping), every
later one the rudder leaving its hold; the heading at an order is the check heading the standard
measures an overshoot from (with a finite rudder rate the ship turns on while the rudder moves, so
measuring from the heading at which the counter-rudder passes some angle understates it).

Every index is read between samples, so that it does not depend on the log rate: an execute where
the steering gear's ramp extrapolates back to the angle it left; a heading crossing (10, 90, 180
deg, the check angle) where a local quadratic through the heading reaches it; a heading extreme
at the maximum of a local cubic; the heading and the track at those times from local
polynomials too, whose windows widen with the heading's noise (which then no longer raises an
overshoot, as the largest noisy sample did). Each index ``<key>`` has its standard uncertainty
``<key>_sd`` beside it, from the residual scatter of those fits and of the rudder's ramps (see
docs/indices.rst).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.polynomial.polynomial as P
from scipy.integrate import cumulative_trapezoid

__all__ = [
    "INDICES",
    "INITIAL_TURN_DEG",
    "ZIGZAG_TIMING",
    "index_keys",
    "manoeuvre_indices",
    "manoeuvre_kind",
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
#: A turn that follows course keeping (small rudder moves, some beyond HOLD_ANGLE) is read as a
#: turning circle when the heading stayed within this (deg) of its course at the execute before it.
APPROACH_HEADING_DEG = 15.0
#: The ramp into a held angle: the steps (between samples) towards it, back from the hold while
#: each is at least this fraction of the largest so far (slower course-keeping moves before the
#: order are not part of it).
RAMP_STEP = 0.25
#: The rudder has started to move once it is further than this from its hold (rad), or four
#: times its noise sd (a steering gear that gathers speed shows this before its ramp).
DEPARTURE = math.radians(0.05)
#: The local fits of a zigzag's heading span, either side of the time they read, the narrowest
#: window that averages the heading's noise down to SMOOTHED_SD_DEG, within these fractions of
#: the time to check yaw: at an execute (a quadratic) and at a heading extreme (a cubic).
CHECK_WINDOW = (0.125, 0.35)
PEAK_WINDOW = (0.35, 0.7)
SMOOTHED_SD_DEG = 0.05
#: The local fits of a turn's heading and track span this fraction of the time from the execute
#: to 90 deg of heading change either side of the time they read.
TURN_WINDOW = 0.125


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


def _noise_sd3(x) -> float:
    """Robust sd of a smooth signal's sample noise, from its third differences (1.4826 MAD /
    sqrt 20): a quadratic trend between samples does not count."""
    d = np.diff(np.asarray(x, float), 3)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(20.0)) if d.size > 2 else 0.0


# --- a signal between its samples -----------------------------------------------------------------
def _der(c, m: int = 1) -> np.ndarray:
    """The ``m``-th derivative of the polynomial ``c`` (increasing powers), as
    :func:`numpy.polynomial.polynomial.polyder` computes it, without its argument handling (it
    is called for every index read, and dominated their cost)."""
    c = np.asarray(c, float)
    for _ in range(m):
        c = c[1:] * np.arange(1, c.size) if c.size > 1 else np.zeros(1)
    return c


@dataclass(frozen=True)
class _Local:
    """A polynomial fitted by least squares to a signal's samples around a time ``tc``: the signal
    between samples, smoothed over the window, with the covariance of its coefficients from the
    residual scatter (the measurement uncertainty of what is read from it)."""

    tc: float
    scale: float
    coef: np.ndarray  # increasing powers of u = (t - tc) / scale
    cov: np.ndarray
    lo: float  # the window's first and last sample times
    hi: float

    def _u(self, tt):
        return (np.asarray(tt, float) - self.tc) / self.scale

    def value(self, tt) -> float:
        return float(P.polyval(self._u(tt), self.coef))

    def slope(self, tt) -> float:
        return float(P.polyval(self._u(tt), _der(self.coef))) / self.scale

    def sd(self, tt) -> float:
        phi = self._u(tt) ** np.arange(self.coef.size)
        return float(math.sqrt(max(phi @ self.cov @ phi, 0.0)))


def _local_fit(t, v, tc: float, half: float, deg: int, lo: float = -math.inf, hi: float = math.inf):
    """The :class:`_Local` polynomial of degree ``deg`` fitted to the samples of ``v`` within
    ``half`` (s) of ``tc`` and within ``[lo, hi]``, widened to the ``deg + 2`` samples nearest
    ``tc`` when the window holds fewer; None with fewer than 2 samples."""
    inside = np.flatnonzero((t >= lo) & (t <= hi))
    idx = inside[np.abs(t[inside] - tc) <= half]
    if idx.size < deg + 2:
        idx = np.sort(inside[np.argsort(np.abs(t[inside] - tc), kind="stable")[: deg + 2]])
    if idx.size < 2:
        return None
    deg = min(deg, idx.size - 1)
    tau = t[idx] - tc
    scale = float(max(np.max(np.abs(tau)), 1e-12))
    X = (tau / scale)[:, None] ** np.arange(deg + 1)
    coef, *_ = np.linalg.lstsq(X, v[idx], rcond=None)
    dof = idx.size - (deg + 1)
    resid = v[idx] - X @ coef
    s2 = float(resid @ resid) / dof if dof > 0 else 0.0
    cov = s2 * np.linalg.pinv(X.T @ X)
    return _Local(float(tc), scale, coef, cov, float(t[idx[0]]), float(t[idx[-1]]))


def _value_at(t, v, tc: float, half: float) -> tuple[float, float, float]:
    """(value, sd, rate of change) of ``v`` at time ``tc``: a local quadratic over ``half`` (s)
    either side (linear between samples when too few)."""
    fit = _local_fit(t, v, tc, half, 2)
    if fit is None:
        return float(np.interp(tc, t, v)), 0.0, 0.0
    return fit.value(tc), fit.sd(tc), fit.slope(tc)


def _approach_at(t, v, s0: float, half: float) -> tuple[float, float, float]:
    """(value, sd, rate of change) of ``v`` at the execute ``s0`` read from the approach: a line
    through the samples within ``half`` (s) before it (at least three). The approach is straight
    and steady, and the turn that starts at the execute (a kink in a synthetic track) does not
    bend it."""
    fit = _local_fit(t, v, s0, half, 1, hi=s0 + 1e-9 * max(1.0, abs(s0)))
    if fit is None:
        return float(np.interp(s0, t, v)), 0.0, 0.0
    return fit.value(s0), fit.sd(s0), fit.slope(s0)


def _reach(t, habs, ang: float, i_from: int, i_to: int, half: float):
    """(time, sd) at which ``habs`` first reaches ``ang`` within samples ``[i_from, i_to]``: where
    the local quadratic of :func:`_local_fit` around the first sample crossing reaches it (linear
    between the two samples when it does not), or None when it never does."""
    k = np.flatnonzero(habs[i_from : i_to + 1] >= ang)
    if not k.size:
        return None
    j = i_from + int(k[0])
    if j == i_from:
        return float(t[j]), 0.0
    h0, h1 = habs[j - 1], habs[j]
    lin = float(t[j - 1] + (ang - h0) / (h1 - h0) * (t[j] - t[j - 1])) if h1 != h0 else float(t[j])
    fit = _local_fit(t, habs, lin, half, 2)
    if fit is None:
        return lin, 0.0
    c = fit.coef.copy()
    c[0] -= ang
    u = _root(c, 0.0)
    tc = None if u is None else fit.tc + fit.scale * u
    if tc is None or not fit.lo <= tc <= fit.hi or not fit.slope(tc) > 0:
        return lin, 0.0
    return float(tc), fit.sd(tc) / fit.slope(tc)


def _root(c, u0: float):
    """The root of the polynomial ``c`` (increasing powers) that Newton's method finds from
    ``u0`` (a local polynomial's root near the sample it was fitted around: its other roots lie
    far away, where a companion-matrix solver loses the near one when the top coefficient is
    small), or None when it does not converge."""
    dc = _der(c)
    u = float(u0)
    for _ in range(100):
        g = float(P.polyval(u, dc))
        if g == 0.0 or not math.isfinite(g):
            return None
        step = float(P.polyval(u, c)) / g
        u -= step
        if abs(u) > 1e3:
            return None
        if abs(step) <= 1e-12 * max(1.0, abs(u)):
            return u
    return None


def _extreme(t, g, t_from: float, t_to: float, half: float):
    """The largest value of ``g`` between times ``t_from`` and ``t_to``, between samples:
    (time, value, sd of time, sd of value). The maximum of a local cubic fitted over ``half``
    (s) either side of the largest sample (and again centred on the maximum found); the largest
    sample itself when the cubic has no maximum in its window (the signal still rising at
    ``t_to``)."""
    seg = np.flatnonzero((t >= t_from) & (t <= t_to))
    j = int(seg[np.argmax(g[seg])])
    tp, found = float(t[j]), None
    for _ in range(2):
        fit = _local_fit(t, g, tp, half, 3, t_from, t_to)
        if fit is None or fit.coef.size < 3:
            break
        u = _root(_der(fit.coef), 0.0)
        tr = None if u is None else fit.tc + fit.scale * u
        if tr is None or not fit.lo <= tr <= fit.hi or not P.polyval(u, _der(fit.coef, 2)) < 0:
            break
        tp, found = tr, (fit, u)
    if found is None:  # the largest sample, as noisy as the signal
        return float(t[j]), float(g[j]), 0.0, _noise_sd3(g[seg])
    fit, u = found
    # the extreme's time moves with the coefficients as -(d p'/d coef) / p'' (implicit function)
    k = np.arange(fit.coef.size)
    dp1 = k * u ** np.clip(k - 1, 0, None)
    grad = -dp1 / float(P.polyval(u, _der(fit.coef, 2)))
    sd_t = fit.scale * float(math.sqrt(max(grad @ fit.cov @ grad, 0.0)))
    return tp, fit.value(tp), sd_t, fit.sd(tp)


# --- the rudder orders ------------------------------------------------------------------------------
def _leg(t, delta, i_from: int, i_to: int, value: float, target: float, noise: float, i_end: int) -> dict:
    """One move of the rudder from ``value`` (a hold, or the approach angle) to ``target`` (the
    next hold), the rudder's noise sd there ``noise``: ``j`` the last sample within ``tol`` of
    ``value`` in ``[i_from, i_to]`` (:data:`ORDER_TOLERANCE` or 4 noise sd), ``on`` the samples
    after it on the way (further than ``tol`` from both ends), ``e`` the first sample within
    ``tol`` of the target (searched up to ``i_end``), ``dev`` the distance from ``value``, ``D``
    the whole move (rad) and ``eps`` the least departure from ``value`` that is not noise
    (:data:`DEPARTURE` or 4 noise sd)."""
    tol = max(ORDER_TOLERANCE, 4.0 * noise)
    dev = np.abs(delta - value)
    near = np.flatnonzero(dev[i_from : i_to + 1] <= tol)
    j = i_from + int(near[-1]) if near.size else i_from
    D = abs(target - value)
    after = np.flatnonzero(dev[j + 1 : i_end + 1] >= D - tol)
    e = j + 1 + int(after[0]) if after.size else None
    on = np.arange(j + 1, e if e is not None else j + 1)
    eps = max(DEPARTURE, 4.0 * noise)
    return {"i_from": i_from, "j": j, "on": on[dev[on] > tol], "e": e, "dev": dev, "D": D, "eps": eps}


def _gear_rate(t, legs) -> float:
    """The steering gear's rate (rad/s) as the record shows it: the median slope of the moves with
    two or more samples on the way; else the steepest slope between consecutive samples of any
    move (a lower bound: the slowest gear consistent with the record) when some move has one;
    infinite when no move has any (the rudder is instantaneous as far as the record shows)."""
    slopes = []
    for leg in legs:
        on = leg["on"]
        if on.size >= 2:
            slopes.append(float(np.polyfit(t[on], leg["dev"][on], 1)[0]))
    slopes = [s for s in slopes if s > 0]
    if slopes:
        return float(np.median(slopes))
    if not any(leg["on"].size for leg in legs):
        return math.inf
    chords = []
    for leg in legs:
        if leg["e"] is not None:
            k = np.arange(leg["j"], leg["e"] + 1)
            chords.append(float(np.max(np.diff(leg["dev"][k]) / np.diff(t[k]))))
    return max(chords) if chords else math.inf


def _ramp_start(t, leg, rate: float, noise: float) -> tuple[float, float]:
    """(time, sd) at which the rudder started to move on ``leg`` (:func:`_leg`): where the line
    through its samples on the way extrapolates back to the hold (two or more of them); one
    sample on the way, less the time to get there at the gear's ``rate``; none, halfway between
    the last sample at the hold and the latest start that reaches the target by the next sample
    at ``rate``, or for an instantaneous rudder (infinite ``rate``) that next sample (an angle
    logged at a sample holds from it on, as a model replays it and as the package's simulations
    log it). A rudder seen leaving its hold earlier than that (a steering gear that gathers
    speed) left it where it first departed by more than ``eps``, linear between samples."""
    j, on, e, dev, D = leg["j"], leg["on"], leg["e"], leg["dev"], leg["D"]
    if j + 1 >= t.size or (e is None and on.size == 0):
        return float(t[j]), 0.0
    if on.size >= 2:
        tt, dd = t[on], dev[on]
        (b, a), cov = np.polyfit(tt - tt[0], dd, 1, cov="unscaled")
        resid = dd - (a + b * (tt - tt[0]))
        s2 = max(float(resid @ resid) / (on.size - 2) if on.size > 2 else 0.0, noise**2)
        start = tt[0] - a / b if b > 0 else float(t[j])
        grad = np.array([a / b**2, -1.0 / b]) if b > 0 else np.zeros(2)  # d start / d (b, a)
        sd = float(math.sqrt(max(s2 * grad @ cov @ grad, 0.0)))
        # a line through the ramp may start before the last sample at the hold (within tol of it)
        start = float(np.clip(start, t[leg["i_from"]], t[j + 1]))
    else:
        if on.size == 1 and math.isfinite(rate):
            start, sd = float(t[on[0]] - dev[on[0]] / rate), noise / rate
        elif math.isfinite(rate):  # the move fell between two samples: it started in between
            latest = max(float(t[e]) - D / rate, float(t[j]))
            start, sd = 0.5 * (t[j] + latest), (latest - float(t[j])) / math.sqrt(12.0)
        else:  # an instantaneous rudder: its angle logged at a sample holds from it on
            start, sd = float(t[e]), float(t[e] - t[j]) / math.sqrt(3.0)
        start = float(np.clip(start, t[j], t[j + 1]))
    # a sample before the start found that is already off the hold by more than eps
    i_from, eps = leg["i_from"], leg["eps"]
    k = np.flatnonzero(dev[i_from : j + 1] <= eps)
    if k.size and i_from + k[-1] < j and t[i_from + k[-1] + 1] < start:
        i = i_from + int(k[-1])
        t_eps = float(t[i] + (eps - dev[i]) / (dev[i + 1] - dev[i]) * (t[i + 1] - t[i]))
        return min(t_eps, start), float(t[i + 1] - t[i]) / math.sqrt(12.0)
    return start, sd


def _snap(t, s: float) -> float:
    """A time within round-off of a sample is that sample's (a simulated order is given at one)."""
    k = int(np.clip(np.searchsorted(t, s), 1, t.size - 1))
    k = k if abs(t[k] - s) <= abs(s - t[k - 1]) else k - 1
    return float(t[k]) if abs(t[k] - s) <= 1e-6 * float(np.median(np.diff(t))) else s


def _plateau(t, delta, a: int, b: int, tol: float):
    """(first, last sample, angle) of the longest run within samples ``[a, b]`` of the rudder
    within ``tol`` (rad) of one angle lasting at least :data:`HOLD_MIN_S`: the angle a hold holds;
    None when it holds none (a slow gear's ramp that only touches its angle)."""
    runs = _constant_rudder(t[a : b + 1], delta[a : b + 1], HOLD_MIN_S, tol)
    if not runs:
        return None
    i, j, angle = max(runs, key=lambda r: t[a + r[1]] - t[a + r[0]])
    return a + i, a + j, angle


def _ramp_back(delta, p: int, lo: int, tol: float, eps: float) -> int:
    """The last sample before the ramp into the held angle whose first sample is ``p``: back from
    ``p`` over the samples still within ``tol`` of it, then over the steps towards it while each
    is more than ``eps`` and at least :data:`RAMP_STEP` of the largest so far, not before ``lo``."""
    angle, k = float(delta[p]), p
    while k > lo and abs(delta[k - 1] - angle) <= tol:
        k -= 1
    if k <= lo:
        return k
    sgn, big = math.copysign(1.0, angle - delta[k - 1]), 0.0
    while k > lo:
        step = sgn * float(delta[k] - delta[k - 1])
        if step <= max(eps, RAMP_STEP * big):
            break
        big, k = max(big, step), k - 1
    return k


def _last_ramp(t, delta, hold, lo: int):
    """The last ramp into a hold's held angle: (j, hold), ``j`` the last sample before it (the
    execute's: the rudder order is given there) and ``hold`` the hold from the ramp on (side,
    first sample beyond :data:`HOLD_ANGLE` after ``j``, last sample, peak |delta| from there);
    the ramp searched back to sample ``lo``. None when the hold holds no angle
    (:func:`_plateau`)."""
    side, a, b, _ = hold
    core = delta[a : b + 1]
    tol = max(ORDER_TOLERANCE, 4.0 * _noise_sd(core))
    got = _plateau(t, delta, a, b, tol)
    if got is None:
        return None
    j = _ramp_back(delta, got[0], lo, tol, max(DEPARTURE, 4.0 * _noise_sd(delta[lo : got[0] + 1])))
    beyond = np.flatnonzero(side * delta[j + 1 : b + 1] > HOLD_ANGLE)
    a2 = j + 1 + int(beyond[0]) if beyond.size else a
    return j, (side, a2, b, float(np.max(np.abs(delta[a2 : b + 1]))))


def _approach_split(t, delta, hold):
    """A first hold that :func:`_rudder_holds` merged with the course keeping before it (rudder
    moves on the same side, the rudder back within :data:`HOLD_ANGLE` between them): (j, hold)
    of :func:`_last_ramp`, the hold from the last ramp into its held angle on; None for a hold
    that starts with that ramp, or one that held its angle before a blip of counter-rudder (one
    order: :func:`_rudder_holds` merges it), or where the held angle is not most of the hold."""
    side, a, b, _ = hold
    got = _last_ramp(t, delta, hold, a)
    if got is None:
        return None
    j, new = got
    if j <= a or not np.any(side * delta[a : j + 1] <= HOLD_ANGLE):
        return None
    if t[new[2]] - t[new[1]] < 0.5 * (t[b] - t[a]):  # a course-keeping stretch, not a turn's hold
        return None
    tol = max(ORDER_TOLERANCE, 4.0 * _noise_sd(delta[new[1] : new[2] + 1]))
    angle = float(delta[new[1] : new[2] + 1][np.argmax(np.abs(delta[new[1] : new[2] + 1]))])
    held_before = _constant_rudder(t[a : j + 1], delta[a : j + 1], HOLD_MIN_S, tol)
    if any(abs(m - angle) <= tol for _, _, m in held_before):
        return None
    return j, new


def _order_into(t, delta, j: int, hold) -> tuple[float, float]:
    """(time, sd) of the order from the rudder angle at sample ``j`` into ``hold``: the start of
    the ramp (:func:`_ramp_start`; the gear's rate read from this ramp alone, the moves before it
    being course keeping, not the gear's)."""
    side, _, b, peak = hold
    noise = _noise_sd(delta[: j + 1])
    leg = _leg(t, delta, j, j, float(delta[j]), side * peak, noise, b)
    s, sd = _ramp_start(t, leg, _gear_rate(t, [leg]), noise)
    return _snap(t, s), (sd if sd > 1e-9 * float(np.median(np.diff(t))) else 0.0)


def rudder_orders(t, delta) -> dict:
    """The rudder orders (executes) of a run, read from its rudder angle.

    Parameters
    ----------
    t : (n,) array
        Time (s).
    delta : (n,) array
        Rudder angle (rad), sampled: the angle at each sample time.

    Returns
    -------
    dict
        ``holds``: the rudder holds (side, first index, last index, peak |delta|): runs beyond
        :data:`HOLD_ANGLE` on one side lasting :data:`HOLD_MIN_S`; ``execute_t_s``: the time of
        each order: the first where the rudder leaves its approach angle before the first hold,
        then where it leaves each hold that another hold follows (ITTC 7.5-04-02-01 Sec. 2.2.2:
        first, second, third ... execute), between samples (the ramp of the steering gear
        extrapolated back to the angle it left; see :func:`manoeuvre_indices`); ``execute_sd_s``
        their standard uncertainties (s); ``executes``: the sample at or before each;
        ``rudder_rate_deg_s``: the steering gear's rate read from the record (inf when every move
        falls between two samples). Empty lists without a hold.
    """
    t, delta = np.asarray(t, float), np.asarray(delta, float)
    holds = _rudder_holds(t, delta, HOLD_ANGLE, HOLD_MIN_S)
    if not holds:
        return {"holds": [], "executes": [], "execute_t_s": [], "execute_sd_s": [], "rudder_rate_deg_s": math.nan}
    split = _approach_split(t, delta, holds[0])
    first = holds[0][1]
    if split is None:
        approach = float(np.median(delta[: first + 1])) if first > 0 else float(delta[0])
        i_from, i_to = 0, first
    else:  # course keeping on the first hold's side before it: the order is the last ramp
        i_from, holds = split[0], [split[1], *holds[1:]]
        first, approach, i_to = holds[0][1], float(delta[split[0]]), split[0]
    noise = _noise_sd(delta[: first + 1])
    legs = [_leg(t, delta, i_from, i_to, approach, holds[0][0] * holds[0][3], noise, holds[0][2])]
    for (side, a, b, peak), nxt in zip(holds[:-1], holds[1:]):
        # the held angle is the hold's peak (a hold can be shorter than the ramps into it); the
        # noise sd of the signal near it widens the tolerance around it
        core = delta[a : b + 1][side * delta[a : b + 1] >= 0.8 * peak]
        legs.append(_leg(t, delta, a, nxt[1], side * peak, nxt[0] * nxt[3], _noise_sd(core), nxt[2]))
    rate = _gear_rate(t, legs)
    starts = [(float(t[0]), 0.0) if first == 0 else _ramp_start(t, legs[0], rate, noise)]
    starts += [_ramp_start(t, leg, rate, noise) for leg in legs[1:]]
    times = [_snap(t, s) for s, _ in starts]
    return {
        "holds": holds,
        "executes": [int(np.searchsorted(t, s + 1e-9 * max(1.0, abs(s)), side="right")) - 1 for s in times],
        "execute_t_s": times,
        "execute_sd_s": [sd if sd > 1e-9 * float(np.median(np.diff(t))) else 0.0 for _, sd in starts],  # no round-off
        "rudder_rate_deg_s": math.degrees(rate),
    }


# --- the indices ------------------------------------------------------------------------------------
def _speed(t, x, y) -> np.ndarray:
    """(n,) speed over ground (m/s) from positions, centred differences over about 1 s."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    k = max(1, int(round(0.5 / dt)))
    i = np.arange(t.size)
    lo, hi = np.clip(i - k, 0, t.size - 1), np.clip(i + k, 0, t.size - 1)
    span = np.where(hi > lo, t[hi] - t[lo], np.nan)
    return np.hypot(x[hi] - x[lo], y[hi] - y[lo]) / span


def _circle_diameter(x, y) -> tuple[float, float]:
    """(diameter, sd) (m) of the least-squares circle through points (algebraic fit: Kasa 1976,
    IEEE Trans. Instrum. Meas. 25(1)); the sd from the radial scatter about it."""
    A = np.column_stack([x, y, np.ones_like(x)])
    b = x * x + y * y
    (cx2, cy2, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    r2 = c + (cx2 / 2) ** 2 + (cy2 / 2) ** 2
    if not r2 > 0:
        return float("nan"), float("nan")
    r = math.sqrt(r2)
    resid = np.hypot(x - cx2 / 2, y - cy2 / 2) - r
    # the radius of a full circle to the radial scatter over sqrt(n) (an arc: somewhat worse)
    sd = float(np.std(resid) / math.sqrt(x.size - 3)) if x.size > 3 else 0.0
    return float(2.0 * r), 2.0 * sd


def _approach_speed(t, speed, s0: float) -> tuple[float, float]:
    """(speed, sd) of the steady approach before the execute at time ``s0``: the median speed over
    the 10 s before it, or NaN when there are fewer than :data:`APPROACH_MIN_S` seconds of
    approach or the speed varies there by more than :data:`APPROACH_SPREAD` of it (a ship still
    accelerating, as the Esso Osaka turns that start from rest: a speed loss then means nothing)."""
    sel = (t >= s0 - 10.0) & (t <= s0) & np.isfinite(speed)
    v = speed[sel]
    if not sel.any() or s0 - t[sel][0] < APPROACH_MIN_S or v.size < 3:
        return float("nan"), float("nan")
    med = float(np.median(v))
    lo, hi = np.percentile(v, [10, 90])
    if not (med > 0 and (hi - lo) <= APPROACH_SPREAD * med):
        return float("nan"), float("nan")
    return med, _median_sd(v)


def _median_sd(v) -> float:
    """Standard error of a median (1.2533 sd / sqrt n)."""
    return float(1.2533 * np.std(v) / math.sqrt(v.size)) if v.size > 1 else 0.0


def _first_order(t, x, y, h, s0: float, sd0: float, hold, t_end: float, half: float) -> dict:
    """What the first rudder order did, for a turn and a zigzag alike: the rudder angle held
    (``rudder_deg``, signed, + port), the speed over ground at the execute ``s0`` (sd ``sd0``)
    (``execute_speed_m_s``: the median over the 10 s before it to 1 s after, the test speed V of
    IMO MSC.137(76) Sec. 4.2.1 read from the run) and the distance travelled along the track from
    the execute until the heading has changed by :data:`INITIAL_TURN_DEG` with the first order
    still in force, i.e. by time ``t_end`` (the end of a turn's hold; a sample past a zigzag's
    second execute, the order to reverse being given where the heading got there)
    (``initial_turning_distance_m``, MSC.137(76) Sec. 5.3.2; MSC/Circ.1053 reads it from the
    10/10 zigzag; NaN when the heading does not get there), each with its ``_sd``."""
    side, _, _, peak = hold
    speed = _speed(t, x, y)
    near = (t >= s0 - 10.0) & (t <= s0 + 1.0) & np.isfinite(speed)
    i0 = max(int(np.searchsorted(t, s0)) - 1, 0)
    i_end = int(np.searchsorted(t, t_end, side="right")) - 1
    got = _reach(t, np.abs(h), math.radians(INITIAL_TURN_DEG), i0, i_end, half)
    # the path length as the integral of the speed (centred differences over about 1 s), which
    # position noise does not inflate as a sum of sample-to-sample steps would
    path = cumulative_trapezoid(np.nan_to_num(speed), t, initial=0.0)
    out = {
        "rudder_deg": float(np.degrees(side * peak)),
        "execute_speed_m_s": float(np.median(speed[near])) if near.any() else float("nan"),
        "execute_speed_m_s_sd": _median_sd(speed[near]) if near.any() else float("nan"),
        "initial_turning_distance_m": float("nan"),
        "initial_turning_distance_m_sd": float("nan"),
    }
    if got is not None and got[0] <= t_end:
        v10 = float(np.interp(got[0], t, np.nan_to_num(speed)))
        out["initial_turning_distance_m"] = float(np.interp(got[0], t, path) - np.interp(s0, t, path))
        v0 = float(np.interp(s0, t, np.nan_to_num(speed)))
        out["initial_turning_distance_m_sd"] = float(math.hypot(v10 * got[1], v0 * sd0))
    return out


def _turning(t, x, y, psi, s0: float, sd0: float, hold) -> tuple[dict, np.ndarray, float]:
    """The turning-circle indices of one rudder hold from the execute at time ``s0`` (sd ``sd0``)
    (ITTC 7.5-04-02-01 Sec. 2.2.1, IMO MSC.137(76) Sec. 4.2.3-4.2.4), each with its ``_sd``; the
    heading change (rad) from the execute; the window (s) of the local fits."""
    _, a, b, _ = hold
    i0 = max(int(np.searchsorted(t, s0)) - 1, 0)
    turned = np.flatnonzero(np.abs(psi[i0 : b + 1] - psi[i0]) >= math.pi / 2)
    half = TURN_WINDOW * (t[i0 + int(turned[0])] - s0) if turned.size else 0.0
    psi0, psi0_sd, _ = _approach_at(t, psi, s0, half)
    x0, x0_sd, u0x = _approach_at(t, x, s0, half)
    y0, y0_sd, u0y = _approach_at(t, y, s0, half)
    h = psi - psi0
    c, s = math.cos(psi0), math.sin(psi0)
    along = c * (x - x0) + s * (y - y0)
    normal = -s * (x - x0) + c * (y - y0)
    # the execute's position: its fit, and its time's uncertainty along the approach course
    across_sd = math.hypot(x0_sd, y0_sd)
    along_sd = math.hypot(across_sd, math.hypot(u0x, u0y) * sd0)
    out = {}
    for ang, keys in ((math.pi / 2, ("advance_m", "transfer_m")), (math.pi, ("tactical_diameter_m",))):
        got = _reach(t, np.abs(h), ang, i0, b, half)
        for key in keys:
            out[key] = out[key + "_sd"] = float("nan")
        if got is None:
            continue
        tc, tc_sd = got
        a_v, a_sd, a_rate = _value_at(t, along, tc, half)
        n_v, n_sd, n_rate = _value_at(t, normal, tc, half)
        if "advance_m" in keys:
            out["advance_m"] = a_v
            out["advance_m_sd"] = math.sqrt(a_sd**2 + (a_rate * tc_sd) ** 2 + along_sd**2 + (n_v * psi0_sd) ** 2)
            out["transfer_m"] = abs(n_v)
            out["transfer_m_sd"] = math.sqrt(n_sd**2 + (n_rate * tc_sd) ** 2 + across_sd**2 + (a_v * psi0_sd) ** 2)
        else:
            out["tactical_diameter_m"] = abs(n_v)
            out["tactical_diameter_m_sd"] = math.sqrt(
                n_sd**2 + (n_rate * tc_sd) ** 2 + across_sd**2 + (a_v * psi0_sd) ** 2
            )
    # steady turning: from 180 deg of heading change to the end of the hold, at least 90 deg of arc
    steady = np.flatnonzero(np.abs(h[a : b + 1]) >= math.pi) + a
    speed = _speed(t, x, y)
    u0, u0_sd = _approach_speed(t, speed, s0)
    out["steady_turning_diameter_m"] = out["steady_turning_diameter_m_sd"] = float("nan")
    out["speed_loss"] = out["speed_loss_sd"] = float("nan")
    if steady.size and abs(h[steady[-1]] - h[steady[0]]) >= math.pi / 2:
        d, d_sd = _circle_diameter(x[steady], y[steady])
        out["steady_turning_diameter_m"], out["steady_turning_diameter_m_sd"] = d, d_sd
        if u0 > 0:
            v = speed[steady][np.isfinite(speed[steady])]
            vs = float(np.median(v))
            out["speed_loss"] = float(1.0 - vs / u0)
            out["speed_loss_sd"] = float(math.hypot(_median_sd(v) / u0, vs * u0_sd / u0**2))
    return out, h, half


def _zigzag(t, psi, starts, sds) -> tuple[dict, np.ndarray, float]:
    """The zigzag indices from the execute times ``starts`` (sd ``sds``) (ITTC 7.5-04-02-01 Sec.
    2.2.2, IMO MSC.137(76) Sec. 4.2.6-4.2.8): overshoots measured from the heading at the 2nd and
    3rd executes, each with its ``_sd``; the heading change (rad) from the first execute; the
    window (s) of the local fits."""
    i1 = int(np.searchsorted(t, starts[1]))
    end1 = starts[2] if len(starts) > 2 else t[-1]
    raw = psi - np.interp(starts[0], t, psi)
    going = float(np.sign(np.interp(starts[1], t, raw)) or 1.0)
    seg = np.flatnonzero((t >= starts[1]) & (t <= end1))
    j = int(seg[np.argmax(going * raw[seg])]) if seg.size else i1
    # the local fits' windows: wide enough to average the heading noise down, within fractions
    # of the time to check yaw (narrow on a clean heading: a polynomial fits it there)
    tcy = max(float(t[j]) - starts[1], 0.0)
    dt = float(np.median(np.diff(t)))
    n = (1.5 * _noise_sd3(raw[int(np.searchsorted(t, starts[0])) :]) / math.radians(SMOOTHED_SD_DEG)) ** 2
    half, peak_half = (float(np.clip(0.5 * n * dt, lo * tcy, hi * tcy)) for lo, hi in (CHECK_WINDOW, PEAK_WINDOW))
    psi0, psi0_sd, _ = _approach_at(t, psi, starts[0], half)
    h = psi - psi0
    checks, local_sd = [], []  # the heading change at each later execute, and its sd about psi0
    for m, sd in zip(starts[1:], sds[1:]):
        v, v_sd, rate = _value_at(t, h, m, half)
        checks.append(float(np.degrees(v)))
        local_sd.append(float(np.degrees(math.hypot(v_sd, rate * sd))))
    out = {
        "check_heading_deg": checks,
        "check_heading_deg_sd": [float(math.hypot(v, np.degrees(psi0_sd))) for v in local_sd],
    }
    orders = starts[1:]
    peaks = []
    for name, k in (("first_overshoot_deg", 0), ("second_overshoot_deg", 1)):
        out[name] = out[name + "_sd"] = float("nan")
        if k >= len(orders):
            continue
        m = orders[k]
        prev_h = float(np.interp(starts[k], t, h))
        going = np.sign(np.radians(checks[k]) - prev_h) or 1.0  # the way the heading turned to this check
        end = orders[k + 1] if k + 1 < len(orders) else float(t[-1])
        tp, gp, tp_sd, gp_sd = _extreme(t, going * (h - np.radians(checks[k])), m, end, peak_half)
        out[name] = float(np.degrees(max(gp, 0.0)))
        out[name + "_sd"] = float(np.hypot(np.degrees(gp_sd), local_sd[k]))
        peaks.append((tp, tp_sd))
    out["overshoot_t_s"] = [p for p, _ in peaks]

    def span(a: int, b: int) -> tuple[float, float]:
        if b >= len(starts):
            return float("nan"), float("nan")
        return starts[b] - starts[a], math.hypot(sds[a], sds[b])

    out["initial_turning_time_s"], out["initial_turning_time_s_sd"] = span(0, 1)
    out["period_s"], out["period_s_sd"] = span(1, 3)
    if peaks:
        out["time_to_check_yaw_s"] = peaks[0][0] - starts[1]
        out["time_to_check_yaw_s_sd"] = math.hypot(peaks[0][1], sds[1])
    else:
        out["time_to_check_yaw_s"] = out["time_to_check_yaw_s_sd"] = float("nan")
    return out, h, half


def manoeuvre_indices(t, x, y, psi, delta, *, check_deg: float | None = None) -> dict:
    """Standard indices of a turning circle or a zigzag from a track, after deciding which
    manoeuvre the run is (module docstring for the sources).

    The rudder is read as holds and orders (:func:`rudder_orders`); the first execute is the
    rudder leaving its approach angle, and the heading change is measured from the heading there
    (the original course). Every time is read between samples and every angle and distance from
    a local least-squares polynomial through the samples around it (docs/indices.rst), so that
    the indices do not depend on the log rate and heading noise is averaged out; each index
    ``<key>`` comes with its standard uncertainty ``<key>_sd`` (same unit), from the residual
    scatter of those fits and the uncertainty of the execute times.

    * **turning**: one hold (the rudder never reversed) during which the heading changes by at
      least 90 deg, or such a last hold after course keeping with the rudder on both sides (the
      heading within :data:`APPROACH_HEADING_DEG` of its course at the execute before it); the
      execute is the start of the last ramp into the held angle, course-keeping moves of the
      rudder before it on the same side are not the order (ITTC 7.5-04-02-01 Sec. 2.2.1): ``advance_m`` (distance along the original course from the execute to 90 deg
      of heading change), ``transfer_m`` (normal to it, at 90 deg), ``tactical_diameter_m``
      (normal distance at 180 deg); ``steady_turning_diameter_m``
      (least-squares circle through the track from 180 deg of heading change to the end of the
      hold, given at least 90 deg of arc) and ``speed_loss`` (1 - steady turning speed /
      approach speed, both from the positions; approach: the 10 s before the execute, NaN
      without a steady approach). NaN where the heading does not get there before the rudder
      returns;
    * **zigzag**: at least two reversals between holds of similar size (each within a factor of
      two of the first), the heading oscillating about the original course (never 90 deg away):
      ``first_overshoot_deg`` and ``second_overshoot_deg`` (the heading's extreme beyond the
      check heading, i.e. the heading at the 2nd and 3rd executes), ``initial_turning_time_s``
      (1st to 2nd execute), ``time_to_check_yaw_s`` (2nd execute to the first heading extreme)
      and ``period_s`` (2nd to 4th execute: one cycle, NaN with fewer executes); also
      ``check_heading_deg`` (the heading change at each later execute, with
      ``check_heading_deg_sd``), ``executes_t_s`` (every execute, with ``executes_t_s_sd``),
      ``overshoot_t_s`` (the times of the two extremes) and, given ``check_deg``,
      ``check_crossing_t_s`` (for each later execute, when the heading change reached the
      nominal check angle on the way to it: the execute minus it is the delay of the order);
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
        Rudder angle (rad): the angle at each sample time.
    check_deg : float, optional
        A zigzag's nominal check angle (deg, positive), when known (a simulated zigzag's, a trial
        plan's): adds ``check_crossing_t_s``. The indices do not depend on it.

    Returns
    -------
    dict
        ``kind`` (``"turning"``, ``"zigzag"``, ``"other"``), ``execute_t_s`` (the first execute,
        with ``execute_t_s_sd``) and the indices of :data:`INDICES` for the kind (a zigzag also
        :data:`ZIGZAG_TIMING`) with the first order's ``rudder_deg``, ``execute_speed_m_s`` and
        ``initial_turning_distance_m``, each index with its ``_sd``; or ``reason``.
    """
    t, x, y, delta = (np.asarray(a, float) for a in (t, x, y, delta))
    psi = np.unwrap(np.asarray(psi, float))
    orders = rudder_orders(t, delta)
    holds, executes = orders["holds"], orders["executes"]
    if not holds:
        return {"kind": "other", "reason": "the rudder is never held beyond 3 deg for 2 s"}
    starts, sds = orders["execute_t_s"], orders["execute_sd_s"]
    i0 = executes[0]
    out = {"execute_t_s": starts[0], "execute_t_s_sd": sds[0]}
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
        got, h, half = _turning(t, x, y, psi, starts[0], sds[0], holds[0])
        return dict(
            out,
            kind="turning",
            **got,
            **_first_order(t, x, y, h, starts[0], sds[0], holds[0], float(t[holds[0][2]]), half),
        )
    turn = _turn_after_approach(t, psi, delta, holds)
    if turn is not None:
        s0, sd0, hold = turn
        got, h, half = _turning(t, x, y, psi, s0, sd0, hold)
        return dict(
            execute_t_s=s0,
            execute_t_s_sd=sd0,
            kind="turning",
            **got,
            **_first_order(t, x, y, h, s0, sd0, hold, float(t[hold[2]]), half),
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
    out["executes_t_s"], out["executes_t_s_sd"] = list(starts), list(sds)
    got, h, half = _zigzag(t, psi, starts, sds)
    if check_deg is not None:
        out["check_crossing_t_s"] = _check_crossings(t, h, starts, math.radians(check_deg), half)
    t_end = float(t[min(holds[0][2], executes[1] + 1)])
    return dict(out, kind="zigzag", **got, **_first_order(t, x, y, h, starts[0], sds[0], holds[0], t_end, half))


def _turn_after_approach(t, psi, delta, holds):
    """A turning circle after course keeping (rudder moves beyond :data:`HOLD_ANGLE` on both
    sides, read as holds): (execute time, sd, hold) when the last hold's last ramp into its held
    angle (:func:`_last_ramp`) came with the heading within :data:`APPROACH_HEADING_DEG` of the
    heading there all along before, and the heading then changed by 90 deg or more while it was
    held; else None."""
    got = _last_ramp(t, delta, holds[-1], 0)
    if got is None:
        return None
    j, hold = got
    _, a, b, _ = hold
    if np.degrees(np.max(np.abs(psi[: j + 1] - psi[j]))) > APPROACH_HEADING_DEG:
        return None
    if np.degrees(np.max(np.abs(psi[a : b + 1] - psi[j]))) < 90.0:
        return None
    s0, sd0 = _order_into(t, delta, j, hold)
    return s0, sd0, hold


def _check_crossings(t, h, starts, check: float, half: float) -> list:
    """For each later execute, the time the heading change reached ``check`` (rad) on the side of
    the check heading there, from the execute before it (NaN when it did not before the next)."""
    out = []
    for k in range(1, len(starts)):
        i_from = max(int(np.searchsorted(t, starts[k - 1])) - 1, 0)
        i_to = int(np.searchsorted(t, starts[k + 1])) if k + 1 < len(starts) else t.size - 1
        side = np.sign(np.interp(starts[k], t, h)) or 1.0
        got = _reach(t, side * h, check, i_from, min(i_to, t.size - 1), half)
        out.append(got[0] if got is not None else float("nan"))
    return out


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


def _side_runs(d, lim: float) -> list:
    """(side, first, last sample) of each run of ``d`` beyond ``lim`` on one side."""
    side = np.where(d > lim, 1, np.where(d < -lim, -1, 0))
    edge = np.flatnonzero(np.diff(side) != 0) + 1
    return [(int(side[i]), int(i), int(j)) for i, j in zip(np.r_[0, edge], np.r_[edge - 1, side.size - 1]) if side[i]]


#: A turn's hold, read from the rudder alone (:func:`manoeuvre_kind`): at least this many times as
#: long as any other excursion beyond half its angle, with the rudder beyond half its angle for at
#: most TURN_APPROACH_BIG of the time before it (course keeping, not a zigzag or a PRBS); released
#: for at most TURN_RELEASE of the hold's length at the end of the record (a trial stopped as the
#: rudder came back), where a pull-out keeps the rudder amidships for longer.
TURN_DOMINANCE = 3.0
TURN_APPROACH_BIG = 0.5
TURN_RELEASE = 0.2


def _turn_kind(t, d, lim: float):
    """``"turning_circle"`` / ``"pull_out"`` when the run's longest hold is a turn's (see
    :data:`TURN_DOMINANCE`) after course keeping, else None (and :func:`manoeuvre_kind`'s general
    rules decide)."""
    runs = _side_runs(d, lim)
    s, i, j = max(runs, key=lambda r: t[r[2]] - t[r[1]])
    dur = float(t[j] - t[i])
    angle = float(np.percentile(np.abs(d[i : j + 1]), 90))
    if not dur > 0 or float(np.mean(np.abs(np.abs(d[i : j + 1]) - angle) < 0.15 * angle)) < 0.6:
        return None
    others = [t[b] - t[a] for _, a, b in _side_runs(d, 0.5 * angle) if b < i or a > j]
    if others and dur < TURN_DOMINANCE * max(others):
        return None
    if i > 0 and float(np.mean(np.abs(d[:i]) > 0.5 * angle)) > TURN_APPROACH_BIG:
        return None
    release = float(t[-1] - t[j])
    if release <= TURN_RELEASE * dur:
        return "turning_circle"
    after = d[j + 1 :]
    return "pull_out" if float(np.mean(np.abs(after) <= lim)) >= 0.8 else None


def manoeuvre_kind(track, hold_deg: float = 2.0) -> str:
    """The standard manoeuvre a logged run most resembles, read from its rudder alone:
    ``"zigzag"`` (two or more reversals of a held rudder), ``"turning_circle"`` (one side, held to
    the end, or a hold that dominates the run after course keeping and lasts to within
    :data:`TURN_RELEASE` of its length of the end), ``"pull_out"`` (one side, then back to
    midships), ``"straight"`` (never beyond
    ``hold_deg``) or ``"other"`` (e.g. a pseudo-random sequence).

    Parameters
    ----------
    track : Track
        A run with ``delta_r`` (rad).
    hold_deg : float, default 2.0
        Rudder angles within this of midships count as midships, deg.

    Returns
    -------
    str
        ``"zigzag"``, ``"turning_circle"``, ``"pull_out"``, ``"straight"`` or ``"other"``.
    """
    d = np.asarray(track["delta_r"], float)
    finite = np.isfinite(d)
    d = d[finite]
    if d.size == 0:
        return "other"
    lim = math.radians(hold_deg)
    side = np.sign(np.where(np.abs(d) > lim, d, 0.0))
    held = side[side != 0]
    if held.size == 0:
        return "straight"
    turn = _turn_kind(np.asarray(track.t, float)[finite], d, lim)
    if turn is not None:
        return turn
    big = np.abs(d[np.abs(d) > lim])
    # one rudder angle held, as a standard run holds it: most rudder-over samples within 15 % of
    # the held angle (the 90th percentile; a 35/5 zigzag of a slow gear spends a fifth ramping)
    held_angle = float(np.percentile(big, 90))
    steady = float(np.mean(np.abs(big - held_angle) < 0.15 * held_angle)) >= 0.6
    # reversals of the held rudder (beyond half the held angle): the small corrections that keep
    # the approach course are not reversals of a zigzag
    over = side[np.abs(d) > max(lim, 0.5 * held_angle)]
    reversals = int(np.count_nonzero(np.diff(over) != 0))
    if reversals >= 2 and steady:
        return "zigzag"
    if reversals == 0 and steady:
        return "turning_circle" if side[-1] != 0 else "pull_out"
    return "other"
