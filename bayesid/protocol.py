"""The window protocol: cut a track into windows that restart from the measured state.

Every held-out score of :mod:`bayesid.analysis.gap` (and of ``bayesid predict``) uses it:

1. cut the track into non-overlapping windows of ``window_s`` seconds from its first sample
   (the last window may be shorter; ``window_s=None`` is one window over the whole run);
2. estimate the state at each window start from measurements *at or before* that time only
   (:func:`state_at`: a causal local-linear fit over ``span_s`` = 1 s; a 2 s span biases a yaw
   rate that is still changing after a rudder step by ~0.8 deg/s, measured on a zigzag);
3. simulate each window open loop from that state with the recorded inputs;
4. pool the squared errors over all samples of all windows of all tracks
   (:func:`pooled_scores`: RMS horizontal position error, heading RMS, per channel RMS).

No window ever sees data from after its start except through the recorded inputs, which a
prediction is allowed to use. Noise levels per channel come from the data alone
(:func:`estimate_noise`).

Two rules give the state at a window start (:data:`START_RULES`); one rule is used for every
model compared on a track set and for its noise floor:

* ``"measured"``: step 2 above. Right when u, v, r are logged by independent sensors (DVL, rate
  gyro); from positions alone the 1 s slope of 0.2 m noise at 5 Hz is off by ~0.1 m/s, metres of
  drift over a 60 s window.
* ``"fitted"`` (moving-horizon estimate, :mod:`bayesid.estimation.shooting`): the window is simulated from
  ``lead-in`` seconds before its start, from a state fitted by least squares to the measured
  channels of that lead-in with the model being scored (the start of multiple shooting proper;
  Bock & Plitt 1984; the moving-horizon estimator of Rao, Rawlings & Mayne 2003 with the
  horizon ending at the window start). The window is scored only on samples at or after its
  start, i.e. after every sample its start used. Training fits estimate the start states of
  their windows jointly with the parameters (variable projection).

``"auto"`` picks ``"fitted"`` when a track does not log all of u, v, r and its positions are too
noisy for a 1 s slope estimate of the velocity (:func:`resolve_start`), else ``"measured"``.

The scores are a :class:`Scores`, a :class:`Record`: the package's one record base, a frozen
dataclass that reads as the JSON dict it writes (the gap diagnosis's records,
:mod:`bayesid.analysis.gap.records`, are Records too).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, fields
from typing import ClassVar

import numpy as np

from .data.track import STATE_NAMES, Track
from .tasks import record_fields

#: Channels scored by the protocol, in this order, when the track measures them.
CHANNELS = ("x", "y", "psi", "u", "v", "r")
#: Smallest noise sd assumed per channel (SI), so that a noise-free channel cannot dominate a fit.
NOISE_FLOOR = {
    "x": 0.01,
    "y": 0.01,
    "z": 0.01,
    "psi": np.radians(0.01),
    "phi": np.radians(0.01),
    "theta": np.radians(0.01),
    "u": 1e-3,
    "v": 1e-3,
    "w": 1e-3,
    "r": np.radians(0.005),
    "p": np.radians(0.005),
    "q": np.radians(0.005),
}
ANGLES = ("phi", "theta", "psi")
#: Window start-state rules (module docstring).
START_RULES = ("auto", "measured", "fitted")
#: Default lead-in (s) of the fitted start rule: long enough that the model, not the position
#: noise, sets the start velocity (0.2 m at 5 Hz over 10 s: about 0.01 m/s), short against a window.
LEADIN_S = 10.0
#: ... and at least this many sample intervals of the slowest log (0.4 m at 1 Hz over 10 samples
#: leaves about 0.05 m/s, 3 m over a 60 s window; over 25 samples about 0.012 m/s).
LEADIN_SAMPLES = 25


#: Largest standard error (m/s) of the measured rule's 1 s causal slope estimate of the velocity
#: from the positions for which ``"auto"`` keeps the measured rule on a track without a velocity
#: log: 0.01 m/s is 0.3 m of drift over a 30 s window. Tank carriage positions (KVLCC2 HSVA, 3e-5 m
#: at 20 Hz) are far below it, GPS-grade logs (0.05 m at 20 Hz: 0.04 m/s) above it.
AUTO_MAX_SLOPE_SD = 0.01


def slope_sd(track: Track, span_s: float = 1.0) -> float:
    """Standard error (m/s) of a least-squares slope of ``x``, ``y`` over ``span_s`` seconds of
    the track's samples: ``sd * sqrt(12 h / span_s**3)`` for position noise ``sd``
    (:func:`estimate_noise`, unfloored) and sample interval ``h`` (the variance of a regression
    slope over N = span_s / h equally spaced samples, ``12 sd^2 / (N span_s^2)``).

    Parameters
    ----------
    track : Track
        The track; its ``x``, ``y`` columns are read.
    span_s : float, default 1.0
        Span of the slope fit, s.

    Returns
    -------
    float
        The standard error, m/s; infinite with fewer than 3 samples in the span or without
        ``x``, ``y``.
    """
    if "x" not in track or "y" not in track or track.n_samples < 3:
        return math.inf
    h = float(np.median(np.diff(track.t)))
    if not h > 0 or span_s / h < 2.0:
        return math.inf
    sd = estimate_noise(track, ["x", "y"], floor=False)
    return max(sd["x"], sd["y"]) * math.sqrt(12.0 * h / span_s**3)


def resolve_start(start: str, tracks) -> str:
    """The start rule for a set of tracks: ``"measured"`` or ``"fitted"``.

    Parameters
    ----------
    start : {"auto", "measured", "fitted"}
        The rule asked for (:data:`START_RULES`). ``"auto"``: measured when every track logs
        u, v and r, or when every track's positions are precise enough for the measured rule's
        slope estimate (:func:`slope_sd` at most :data:`AUTO_MAX_SLOPE_SD`); else fitted.
    tracks : iterable of Track
        The tracks the rule is for.

    Returns
    -------
    str
        ``"measured"`` or ``"fitted"``.

    Raises
    ------
    ValueError
        Naming an unknown rule.
    """
    if start not in START_RULES:
        raise ValueError(f"start rule must be one of {', '.join(START_RULES)}, not {start!r}")
    if start != "auto":
        return start
    logged = all(k in tr and np.isfinite(np.asarray(tr[k], float)).any() for tr in tracks for k in ("u", "v", "r"))
    if logged or all(slope_sd(tr) <= AUTO_MAX_SLOPE_SD for tr in tracks):
        return "measured"
    return "fitted"


def wrap(a):
    """Angle(s) wrapped to [-pi, pi) (rad).

    Parameters
    ----------
    a : float or array_like
        Angle(s), rad.

    Returns
    -------
    ndarray or float
        The wrapped angle(s), rad, of the shape of ``a``.
    """
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def estimate_noise(track: Track, channels=None, floor: bool = True) -> dict:
    """Measurement-noise standard deviation of each state channel, from the data alone.

    Difference-based estimator (Gasser, Sroka & Jennen-Steinmetz 1986, Biometrika 73(3),
    pseudo-residuals ``(y[i-1] - 2 y[i] + y[i+1]) / sqrt(6)``), made robust with the median
    absolute deviation (``1.4826 * MAD``) so that manoeuvre transients do not count as noise
    (:func:`difference_noise_sd`). In a coarse log (under about 7 Hz), where a manoeuvre's own
    curvature enters the second differences (at 1-5 Hz a zigzag's yaw acceleration in a quiet
    sensor's log), the fourth, then the sixth differences take over (Hall, Kay & Titterington
    1990, Biometrika 77(3)). Assumes samples that are roughly uniform in time; headings are
    unwrapped first. The result is floored at :data:`NOISE_FLOOR` (the weights of a fit) unless
    ``floor`` is False (the noise level itself, e.g. to simulate it).

    Parameters
    ----------
    track : Track
        The track, with at least 3 samples.
    channels : sequence of str, optional
        State names to estimate; default the track's state columns.
    floor : bool, default True
        Floor each sd at :data:`NOISE_FLOOR`.

    Returns
    -------
    dict
        ``{name: sd}`` in the channel's SI unit (m, rad, m/s, rad/s).

    Raises
    ------
    ValueError
        Fewer than 3 samples; a requested channel absent (named).
    """
    names = list(track.state_columns if channels is None else channels)
    if track.n_samples < 3:
        raise ValueError(f"track {track.name!r}: need >= 3 samples to estimate noise")
    out = {}
    for k in names:
        if k not in track:
            raise ValueError(f"track {track.name!r} has no column {k!r} to estimate noise from")
        y = np.asarray(track[k], float)
        ok = np.isfinite(y)
        y = y[ok]
        if y.size < 3:
            out[k] = NOISE_FLOOR.get(k, 0.0) if floor else 0.0
            continue
        if k in ANGLES:
            y = np.unwrap(y)
        sd = difference_noise_sd(y, float(np.median(np.diff(track.t[ok]))))
        out[k] = max(sd, NOISE_FLOOR.get(k, 0.0)) if floor else sd
    return out


#: Orders of the differences :func:`difference_noise_sd` reads, lowest first
DIFFERENCE_ORDERS = (2, 4, 6)
#: A higher order of differences replaces a lower one when the lower reads more than this many
#: times its noise (the motion in the lower order's differences). Pure noise gives the orders
#: alike (a ratio under 1.3 in 99 % of 100-sample records, ``tests/test_noise_floor.py``).
DIFFERENCE_RATIO = 1.3
#: Logs sampled at least this far apart (s; under about 7 Hz) are coarse: only there do the higher
#: orders of :func:`difference_noise_sd` take over (issue 69 asked for 1-5 Hz; the benchmark
#: ``benchmarks/noise_rate.py`` measured second differences reading a zigzag as 1.3-4 x its noise
#: at 5 Hz and 2-100 x at 1-2 Hz, within 5 % at 20 Hz). Finer logs keep the second differences, as
#: every committed study was calibrated: there the orders disagree only where a channel has next
#: to no noise (the HSVA logs' y and psi at 20 Hz read 1.35-1.65 x, the Esso Osaka logs' smooth r
#: at 10 Hz 100 x), and the floors of a fit (:data:`NOISE_FLOOR`) and of a diagnosis are then far
#: under the model's error anyway.
COARSE_LOG_S = 0.15


def _mad_sd(y, order: int) -> float:
    """1.4826 x the MAD of the ``order``-th differences of ``y``, each divided by the norm of its
    binomial coefficients (the square root of C(2 order, order): 6, 70, 924)."""
    if order == 2:  # written out: the estimate of the package's earlier versions, to the bit
        d = (y[:-2] - 2.0 * y[1:-1] + y[2:]) / np.sqrt(6.0)
    else:
        d = np.diff(y, order) / math.sqrt(math.comb(2 * order, order))
    return 1.4826 * float(np.median(np.abs(d - np.median(d))))


def difference_noise_sd(y, interval_s: float) -> float:
    """Robust noise sd of one uniformly sampled channel from its differences.

    The second differences' estimate (Gasser, Sroka & Jennen-Steinmetz 1986). In a coarse log
    (``interval_s`` at least :data:`COARSE_LOG_S`), where a manoeuvre's curvature enters the second
    differences (a zigzag's yaw acceleration at 1-5 Hz), the fourth differences' estimate replaces
    it when it is :data:`DIFFERENCE_RATIO` times smaller, and the sixth's the fourth's by the same
    test (Hall, Kay & Titterington 1990, Biometrika 77(3): differences of order 2m cancel a
    polynomial of degree 2m - 1 of motion). Each order's differences are normalised to unit
    variance under white noise, and the estimate is ``1.4826 * MAD`` of them.

    Parameters
    ----------
    y : array_like, shape (n,)
        The finite samples of one channel (angles unwrapped), n >= 3.
    interval_s : float
        The log's sample interval (the median), s.

    Returns
    -------
    float
        The noise sd, in the channel's unit.
    """
    y = np.asarray(y, float)
    sd = _mad_sd(y, 2)
    if not interval_s >= COARSE_LOG_S:
        return sd
    for order in DIFFERENCE_ORDERS[1:]:
        if y.size <= order:
            break
        higher = _mad_sd(y, order)
        if not sd > DIFFERENCE_RATIO * higher:
            break
        sd = higher
    return sd


def window_starts(t, window_s: float | None) -> np.ndarray:
    """Start times of the protocol's non-overlapping windows over ``t``.

    Windows start at ``t[0] + i * window_s`` for every i whose start lies before ``t[-1]``.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times, s.
    window_s : float or None
        Window length, s; None gives one window.

    Returns
    -------
    ndarray
        The start times, s (at least one).

    Raises
    ------
    ValueError
        For a non-positive window.
    """
    t = np.asarray(t, float)
    if window_s is None:
        return t[:1].copy()
    if not window_s > 0:
        raise ValueError(f"window must be positive (s), got {window_s}")
    n = int(np.ceil((t[-1] - t[0]) / window_s - 1e-9))
    return t[0] + window_s * np.arange(max(n, 1))


def _causal_fit(t, y, t0, span_s, degree=1):
    """Value at t0 of a local polynomial fitted to the finite samples in [t0 - span_s, t0]."""
    sel = (t <= t0 + 1e-9) & (t >= t0 - span_s - 1e-9) & np.isfinite(y)
    ts, ys = t[sel], y[sel]
    if ts.size == 0:
        return np.nan
    deg = min(degree, ts.size - 1)
    if deg == 0:
        return float(ys[-1])
    c = np.polyfit(ts - t0, ys, deg)
    return float(c[-1])


def state_at(track: Track, t0: float, span_s: float = 1.0) -> np.ndarray:
    """Estimate of the 12-state at time ``t0`` from measurements at or before ``t0`` only.

    Each measured state channel: a local-linear least-squares fit over ``[t0 - span_s, t0]``
    evaluated at ``t0`` (headings unwrapped first; the last sample alone when it is the only
    one). Unmeasured ``u``, ``v`` (or ``r``): the causal local-quadratic slope of ``x, y`` (or
    ``psi``) over ``2*span_s``, rotated into the body frame (horizontal kinematics, Fossen 2011,
    Ch. 2). Any other unmeasured state is 0.

    Parameters
    ----------
    track : Track
        The track; it must have ``x``, ``y`` and ``psi``.
    t0 : float
        The time of the state, s.
    span_s : float, default 1.0
        Span of the local-linear fit, s.

    Returns
    -------
    ndarray, shape (12,)
        The state in :data:`~bayesid.data.track.STATE_NAMES` order (SI).

    Raises
    ------
    ValueError
        No sample at or before ``t0``; ``x``, ``y`` or ``psi`` missing.
    """
    t = track.t
    if t0 < t[0] - 1e-9:
        raise ValueError(f"track {track.name!r}: no sample at or before t = {t0:g} s")
    for k in ("x", "y", "psi"):
        if k not in track:
            raise ValueError(f"track {track.name!r} has no column {k!r}; the protocol needs x, y, psi")
    s = np.zeros(12)
    # only the samples this estimate can use (unwrapping the whole channel for every window would
    # make the protocol quadratic in the track length)
    lo, hi = (
        np.searchsorted(t, [t0 - 2 * span_s - 1e-9, t0 + 1e-9], side="left")[0],
        np.searchsorted(t, t0 + 1e-9, side="right"),
    )
    t = t[lo:hi]
    for i, k in enumerate(STATE_NAMES):
        if k in track:
            y = np.asarray(track[k], float)[lo:hi]
            if k in ANGLES:
                y = _unwrap_finite(y)
            val = _causal_fit(t, y, t0, span_s)
            s[i] = wrap(val) if k in ANGLES and np.isfinite(val) else val
    psi = s[5]
    need = [k for k in ("u", "v", "r") if k not in track or not np.isfinite(s[STATE_NAMES.index(k)])]
    if need:
        sel = (t <= t0 + 1e-9) & (t >= t0 - 2 * span_s - 1e-9)
        ts = t[sel] - t0
        slope = {}
        for k in ("x", "y", "psi"):
            y = np.asarray(track[k], float)[lo:hi][sel]
            if k == "psi":
                y = _unwrap_finite(y)
            ok = np.isfinite(y)
            slope[k] = float(np.polyfit(ts[ok], y[ok], min(2, ok.sum() - 1))[-2]) if ok.sum() >= 2 else 0.0
        est = _body_rates(slope, psi)
        for k in need:
            s[STATE_NAMES.index(k)] = est[k]
    return np.where(np.isfinite(s), s, 0.0)


def start_settings(
    start: str, tracks, window_s: float | None, dt: float, leadin_s: float | None = None
) -> tuple[str, float]:
    """Rule and lead-in of the window start states for a set of tracks.

    Parameters
    ----------
    start : {"auto", "measured", "fitted"}
        The rule asked for, resolved by :func:`resolve_start`.
    tracks : sequence of Track
        The tracks.
    window_s : float or None
        Protocol window, s (None: one window per run); the lead-in is at most the window.
    dt : float
        Model step, s.
    leadin_s : float, optional
        Lead-in of the fitted rule, s; by default the larger of :data:`LEADIN_S` and
        :data:`LEADIN_SAMPLES` median sample intervals of the slowest track, rounded up to a
        multiple of ``dt``.

    Returns
    -------
    rule : str
        ``"measured"`` or ``"fitted"``.
    leadin_s : float
        The lead-in, s (at most the window); 0 for the measured rule.

    Raises
    ------
    ValueError
        For an unknown rule or a negative lead-in.
    """
    rule = resolve_start(start, tracks)
    if rule != "fitted":
        return rule, 0.0
    if leadin_s is None:
        h = max((float(np.median(np.diff(t.t))) for t in tracks if t.n_samples > 1), default=0.0)
        lead = math.ceil(max(LEADIN_S, LEADIN_SAMPLES * h) / dt - 1e-9) * dt
    else:
        lead = float(leadin_s)
        if not lead >= 0:
            raise ValueError(f"lead-in must be >= 0 s, not {leadin_s}")
    return rule, lead if window_s is None else min(lead, float(window_s))


def state_guess(track: Track, t_a: float, span_s: float = 2.0) -> np.ndarray:
    """First guess of the 12-state at ``t_a`` from the samples in ``[t_a, t_a + span_s]`` (the
    start of a lead-in or of a training window; the fitted start rule refines it).

    Measured channels: local-linear fit evaluated at ``t_a`` (headings unwrapped; ``x``, ``y``,
    ``psi`` local-quadratic); unmeasured ``u``, ``v``, ``r``: the local-quadratic slope of
    ``x, y`` (``psi``) rotated into the body frame; any other unmeasured state 0.

    Parameters
    ----------
    track : Track
        The track; it must have ``x``, ``y`` and ``psi``.
    t_a : float
        The time of the state, s.
    span_s : float, default 2.0
        Span of the fit after ``t_a``, s.

    Returns
    -------
    ndarray, shape (12,)
        The state in :data:`~bayesid.data.track.STATE_NAMES` order (SI).

    Raises
    ------
    ValueError
        When ``x``, ``y`` or ``psi`` is missing.
    """
    t = track.t
    for k in ("x", "y", "psi"):
        if k not in track:
            raise ValueError(f"track {track.name!r} has no column {k!r}; the protocol needs x, y, psi")
    sel = (t >= t_a - 1e-9) & (t <= t_a + span_s + 1e-9)
    ts = t[sel] - t_a
    s = np.full(12, np.nan)
    slope = {}
    for i, k in enumerate(STATE_NAMES):
        if k not in track:
            continue
        y = np.asarray(track[k], float)[sel]
        if k in ANGLES:
            y = _unwrap_finite(y)
        ok = np.isfinite(y)
        if ok.sum() == 0:
            continue
        deg = min(2 if k in ("x", "y", "psi") else 1, ok.sum() - 1)
        c = np.polyfit(ts[ok], y[ok], deg) if deg > 0 else np.array([y[ok][0]])
        s[i] = c[-1]
        if k in ("x", "y", "psi"):
            slope[k] = float(c[-2]) if deg > 0 else 0.0
    s[5] = wrap(s[5]) if np.isfinite(s[5]) else 0.0
    est = _body_rates(slope, s[5])
    for k, v in est.items():
        i = STATE_NAMES.index(k)
        if not np.isfinite(s[i]):
            s[i] = v
    return np.where(np.isfinite(s), s, 0.0)


def _body_rates(slope: dict, psi: float) -> dict:
    """u, v, r from the earth-frame slopes of x, y (m/s) and psi (rad/s) at heading psi (missing
    slopes count as 0; horizontal kinematics, Fossen 2011, Ch. 2)."""
    dx, dy = slope.get("x", 0.0), slope.get("y", 0.0)
    c, sn = np.cos(psi), np.sin(psi)
    return {"u": c * dx + sn * dy, "v": -sn * dx + c * dy, "r": slope.get("psi", 0.0)}


def _unwrap_finite(y):
    out = np.array(y, float)
    ok = np.isfinite(out)
    out[ok] = np.unwrap(out[ok])
    return out


#: The strings strict JSON writes for non-finite floats (:func:`bayesid.tasks.jsonable`).
_NON_FINITE = ("nan", "inf", "-inf")


class Record(Mapping):
    """The package's record base: a dataclass that reads as the JSON dict it writes (the protocol's
    :class:`Scores`, and the gap diagnosis's records, :mod:`bayesid.analysis.gap.records`).

    A subclass is a ``@dataclass(frozen=True, eq=False)`` (``eq=False`` keeps the mapping's
    equality, so a record equals the dict it writes). Its JSON object has a key per field, in
    field order, but the fields of ``_OPTIONAL`` while they are None; ``_ALIASES`` (``{alias:
    field}``) are written right after their field, with its value.
    """

    #: Fields left out of the JSON (and of the mapping) while None.
    _OPTIONAL: ClassVar[tuple] = ()
    #: ``{alias: field}``: keys written after their field, with its value.
    _ALIASES: ClassVar[dict] = {}
    #: The record's name in messages.
    _WHAT: ClassVar[str] = "record"

    def _keys(self) -> tuple:
        out = []
        for f in fields(self):
            if f.name in self._OPTIONAL and getattr(self, f.name) is None:
                continue
            out.append(f.name)
            out += [a for a, n in self._ALIASES.items() if n == f.name]
        return tuple(out)

    def to_dict(self) -> dict:
        """The record as its JSON object (dicts and lists copied, one level).

        Returns
        -------
        dict
            ``{key: value}`` in the order the diagnosis has always written them.
        """
        return {k: _copy(self._value(k)) for k in self._keys()}

    @classmethod
    def from_dict(cls, d: Mapping):
        """The record of a JSON object :meth:`to_dict` wrote (``"nan"``, ``"inf"``, ``"-inf"``
        in a float field read as floats).

        Parameters
        ----------
        d : Mapping
            The JSON object.

        Returns
        -------
        Record
            The record; ``cls.from_dict(x).to_dict() == x``.

        Raises
        ------
        ValueError
            A key the record does not have, or a required one missing (named).
        """
        args = record_fields(cls, d, cls._WHAT, extra=tuple(cls._ALIASES))
        kinds = {f.name: str(f.type) for f in fields(cls)}
        return cls(**{k: read_float(v) if kinds[k].startswith("float") else v for k, v in args.items()})

    @classmethod
    def read(cls, d: Mapping):
        """The record of a JSON object of the record's current shape, else the object as read: a
        row of an older file (written before a field existed) or a hand-made one stays a dict, so
        that writing it again gives it back key for key.

        Parameters
        ----------
        d : Mapping
            The JSON object.

        Returns
        -------
        Record or dict
            ``cls.from_dict(d)`` when that writes ``d``'s keys in ``d``'s order, else ``dict(d)``.
        """
        try:
            rec = cls.from_dict(d)
        except ValueError:
            return dict(d)
        return rec if list(rec) == list(d) else dict(d)

    def _value(self, key: str):
        return getattr(self, self._ALIASES.get(key, key))

    def __getitem__(self, key: str):
        if key in self._keys():
            return self._value(key)
        raise KeyError(key)

    def __iter__(self):
        return iter(self._keys())

    def __len__(self) -> int:
        return len(self._keys())


def _copy(v):
    return dict(v) if isinstance(v, dict) else list(v) if isinstance(v, list) else v


def read_float(v):
    """A JSON value with the strings strict JSON writes for non-finite floats read back as floats.

    Parameters
    ----------
    v : object
        A value read from JSON (``"nan"``, ``"inf"`` and ``"-inf"`` are what
        :func:`bayesid.tasks.jsonable` writes for non-finite floats).

    Returns
    -------
    object
        The float for one of those strings; any other value as it is.
    """
    return float(v) if isinstance(v, str) and v in _NON_FINITE else v


@dataclass(frozen=True, eq=False)
class Scores(Record):
    """The protocol's scores of a model on a set of tracks: a frozen record that also reads as the
    JSON dict it writes (``scores["rms_position_m"]``, ``dict(scores)``), as scipy's
    ``OptimizeResult`` does.

    Parameters
    ----------
    rms : dict
        ``{channel: RMS error}`` over every window's samples, SI (``x``, ``y`` m, ``psi`` rad,
        ``u``, ``v`` m/s, ``r`` rad/s; the channels scored).
    rms_position_m : float
        sqrt of the mean of ex^2 + ey^2, m (NaN without ``x``, ``y``).
    max_position_m : float
        The largest horizontal position error, m.
    rms_heading_deg : float
        Heading RMS, deg (NaN without ``psi``).
    n_samples : int
        Samples of ``x`` scored.
    per_track_rms_position_m : dict, optional
        ``{track name: position RMS, m}`` (:func:`bayesid.estimation.windows.scores`).
    log_likelihood : float, optional
        Gaussian log-likelihood of the errors at given sds, nats
        (:func:`bayesid.estimation.windows.scores`).

    Notes
    -----
    The optional fields are left out of :meth:`to_dict` (and of the mapping) when None, so the
    JSON is the dict :func:`pooled_scores` returned before it was a record.
    """

    rms: dict
    rms_position_m: float
    max_position_m: float
    rms_heading_deg: float
    n_samples: int
    per_track_rms_position_m: dict | None = None
    log_likelihood: float | None = None

    _OPTIONAL: ClassVar[tuple] = ("per_track_rms_position_m", "log_likelihood")
    _WHAT: ClassVar[str] = "scores"

    @classmethod
    def from_dict(cls, d: Mapping) -> Scores:
        """The record of a dict :meth:`to_dict` wrote (e.g. read back from a JSON file).

        Parameters
        ----------
        d : Mapping
            The scores' keys.

        Returns
        -------
        Scores
            The record.

        Raises
        ------
        ValueError
            A key the record does not have, or a required one missing (named).
        """
        names = [f.name for f in fields(cls)]
        unknown = [k for k in d if k not in names]
        if unknown:
            raise ValueError(f"scores: unknown key(s) {unknown} (known: {names})")
        missing = [f.name for f in fields(cls) if f.default is MISSING and f.name not in d]
        if missing:
            raise ValueError(f"scores: missing key(s) {missing}")
        return cls(**{k: _number(v) for k, v in d.items()})

    def __repr__(self) -> str:
        return f"Scores({', '.join(f'{k}={v!r}' for k, v in self.items())})"


def _number(v):
    """``v`` with the strings strict JSON writes for non-finite floats (``"nan"``, ``"inf"``,
    ``"-inf"``) read back as floats, in dicts too."""
    if isinstance(v, dict):
        return {k: _number(x) for k, x in v.items()}
    return float(v) if isinstance(v, str) else v


def pooled_scores(errors: list[dict]) -> Scores:
    """Pool per-sample errors of many windows/tracks into the protocol's scores.

    Parameters
    ----------
    errors : list of dict
        One ``{channel: array (n_i,)}`` per window: prediction minus measurement per channel
        (``x``, ``y`` m, ``psi`` rad wrapped, ``u``, ``v`` m/s, ``r`` rad/s; any subset).

    Returns
    -------
    Scores
        ``rms_position_m`` (sqrt of the mean of ex^2 + ey^2; NaN without ``x``, ``y``),
        ``max_position_m``, ``rms_heading_deg`` (NaN without ``psi``), ``rms`` (``{channel:
        RMS}``, SI) and ``n_samples`` (of ``x``).
    """
    cat = {}
    for e in errors:
        for k, v in e.items():
            cat.setdefault(k, []).append(np.asarray(v, float))
    cat = {k: np.concatenate(v) for k, v in cat.items()}
    rms = {k: float(np.sqrt(np.nanmean(v**2))) if v.size else float("nan") for k, v in cat.items()}
    pos = mx = float("nan")
    if "x" in cat and "y" in cat and cat["x"].size:
        d2 = cat["x"] ** 2 + cat["y"] ** 2
        pos, mx = float(np.sqrt(np.nanmean(d2))), float(np.sqrt(np.nanmax(d2)))
    return Scores(
        rms=rms,
        rms_position_m=pos,
        max_position_m=mx,
        rms_heading_deg=float(np.degrees(rms["psi"])) if "psi" in rms else float("nan"),
        n_samples=int(cat["x"].size) if "x" in cat else 0,
    )


__all__ = [
    "CHANNELS",
    "NOISE_FLOOR",
    "START_RULES",
    "LEADIN_S",
    "wrap",
    "estimate_noise",
    "difference_noise_sd",
    "DIFFERENCE_ORDERS",
    "DIFFERENCE_RATIO",
    "COARSE_LOG_S",
    "window_starts",
    "state_at",
    "state_guess",
    "resolve_start",
    "start_settings",
    "LEADIN_SAMPLES",
    "Record",
    "read_float",
    "Scores",
    "pooled_scores",
]
