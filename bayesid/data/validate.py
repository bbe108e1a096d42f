"""Semantic checks of a track before anything is fitted to it: units, consistency between
channels, plausibility for the vehicle.

:func:`bayesid.data.track.read_csv` checks the syntax (numbers, increasing time, known units in the
header). A log can pass it and still be in the wrong units: heading or rudder in degrees, time in
milliseconds, speeds in knots, yaw rate in deg/s, propeller speed in rev/s. These are detected
from ranges and from consistency (yaw rate against the heading's rate, body speed against the
position increments, sample interval against speed) and refused with a message naming the file,
the column and the unit it looks like. Things that may be real but deserve a look (propeller
stopped throughout, a speed far outside the vehicle's range) come back as warnings, which the
commands print and record in their outputs, and which :func:`bayesid.identify` raises as Python
warnings of the category :class:`TrackWarning` (a :class:`BayesidWarning`), so that the API says
what the commands say.
"""

from __future__ import annotations

import math
import re

import numpy as np

from .track import INPUT_NAMES, Track, clock, continuous_pieces


class BayesidWarning(UserWarning):
    """Base of the package's warnings: ``warnings.simplefilter("error", BayesidWarning)`` makes
    every one of them an error, ``"ignore"`` silences them (the commands print their own)."""


#: The command options the track checks' and the step check's advice names, and the option of the
#: Python API that does the same (a warning raised by :func:`bayesid.identify` names both)
API_OPTIONS = {
    "--inputs rate": 'FitOptions(inputs="rate")',
    "--inputs hold": 'FitOptions(inputs="hold")',
    "--rudder-rate": "FitOptions(rudder_rate_deg_s=...)",
    "--retime": "FitOptions(retime=True)",
    "--dt auto": "FitOptions(refine_step=True)",
    "--vehicle": "the vehicle given to identify",
}


def in_api_terms(message: str) -> str:
    """A message of the track checks or the step check with the Python API's name of each command
    option it names appended (``--inputs rate`` is ``FitOptions(inputs="rate")``), for the
    warnings the API raises.

    Parameters
    ----------
    message : str
        The advice as the commands print it.

    Returns
    -------
    str
        The same text, followed by ``(in the Python API: ...)`` when it names an option of
        :data:`API_OPTIONS`.
    """
    said = [f"{cli} is {api}" for cli, api in API_OPTIONS.items() if cli in message]
    return f"{message} (in the Python API: {'; '.join(said)})" if said else message


class TrackWarning(BayesidWarning):
    """A track that passed its checks but deserves a look (:func:`check_track`'s warnings: a
    coarse log for the inputs, a propeller at 0 rpm while moving, a wrapped heading, a rudder past
    the vehicle's limit, ...)."""


#: (factor, unit) pairs a speed column is recognised in when its ratio to the ground speed from
#: the positions is within 15 % of the factor.
SPEED_UNITS = ((3.6, "km/h"), (1.0 / 0.514444, "knots"), (100.0, "cm/s"))
#: (factor, unit) pairs the time column is recognised in when the positions (or heading) change
#: the factor x faster per time unit than the body speeds (yaw rate) say.
TIME_UNITS = ((60.0, "minutes"), (3600.0, "hours"), (0.001, "milliseconds"))
#: (factor, unit) pairs positions are recognised in when the body speed (m/s) is within 15 % of
#: the factor x the speed from the positions.
POSITION_UNITS = ((1000.0, "km"), (1852.0, "nautical miles"), (0.3048, "feet"))


def _ratio(a, b):
    """Median of |a| / |b| over the samples where both are finite and |b| is well above zero."""
    a, b = np.abs(np.asarray(a, float)), np.abs(np.asarray(b, float))
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 10:
        return None
    thr = np.percentile(b[ok], 50)
    sel = ok & (b > max(thr, 1e-12))
    return float(np.median(a[sel] / b[sel])) if sel.sum() >= 5 else None


#: A run of empty cells in an input column is a hole when the logged values on either side of it
#: are more than this many sample intervals apart (the track's or, for an input logged more slowly,
#: its own median interval; the rule of :func:`bayesid.data.track.continuous_pieces`).
HOLE_INTERVALS = 5.0
#: A vessel moving faster than this (m/s, median) with its propeller at 0 rpm in every row gets a
#: warning: a propeller that was not logged, rather than a ship drifting.
MOVING_SPEED = 0.1


def _runs(mask) -> list[tuple[int, int]]:
    """(first, last) sample indices of each run of True in ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1).tolist(), (np.flatnonzero(d == -1) - 1).tolist()))


def _rows(track: Track, i: int, j: int) -> str:
    """The "rows a-b" of the file (1-based line numbers) of samples i..j, where the track knows its
    file's rows (:func:`~bayesid.data.track.read_csv`, no blank lines among the data), else the
    samples' 1-based numbers."""
    first, last = track.meta.get("file_rows", (None, None))
    if first is not None and last - first + 1 == track.n_samples:
        return f"rows {first + i}-{first + j}"
    return f"samples {i + 1}-{j + 1}"


def input_gaps(track: Track, where: str | None = None) -> None:
    """Refuse a hole in a logged input: a run of empty cells in ``delta_r``, ``delta_s``,
    ``delta_b`` or ``n`` that lasts longer than :data:`HOLE_INTERVALS` sample intervals.

    The models hold an input's last logged value over a few empty cells (a dropped sample, or an
    input logged more slowly than the positions); over a hole they would fly on a rudder or
    propeller nobody logged, and the window protocol would quietly leave that stretch out. A
    command therefore stops and says where the hole is.

    Parameters
    ----------
    track : Track
        The track; its input columns (:data:`~bayesid.data.track.INPUT_NAMES`) are checked.
    where : str, optional
        The file named in messages; default the track's name.

    Raises
    ------
    ValueError
        A hole (or a column without any value), naming the file, the column, the rows (1-based
        line numbers in the file) and the times of its empty cells.
    """
    name = where or track.name
    t = track.t
    h = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    for col in INPUT_NAMES:
        if col not in track:
            continue
        fin = np.flatnonzero(np.isfinite(track[col]))
        own = float(np.median(np.diff(t[fin]))) if fin.size > 2 else h
        limit = HOLE_INTERVALS * max(h, own)
        # the logged values around each run of empty cells (-1, n: the ends of the track)
        around = np.r_[-1, fin, t.size]
        for a, b in zip(around[:-1], around[1:]):
            if b - a < 2:
                continue
            i, j = int(a) + 1, int(b) - 1
            held = (t[b] if b < t.size else t[-1] + h) - (t[a] if a >= 0 else t[0] - h)
            if held > limit + 1e-9 or fin.size == 0:
                whole = " (the whole track)" if i == 0 and j == t.size - 1 else ""
                raise ValueError(
                    f"{name}: column '{col}': empty in {_rows(track, i, j)} (t = {clock(t[i])} to {clock(t[j])} s, "
                    f"{t[j] - t[i] + h:.3g} s{whole}): no logged {col} to simulate with there (an input may "
                    f"miss at most {HOLE_INTERVALS:g} sample intervals in a row); fill in the logged "
                    "values, or split the file at the hole, one track file per piece"
                )


#: The packaged vehicles and the words by which a track's ``# vessel:`` line names them.
PACKAGED_VESSELS = {"nps_auv2": ("nps", "auv2", "sdv"), "esso_osaka_3m": ("esso",), "kvlcc2_7m": ("kvlcc2",)}


_GENERIC = frozenset(
    "model vehicle ship boat vessel hull scale full the and with from coefficients of "
    "form test tests data pond tank free running".split()
)


def _words(text: str) -> set[str]:
    """Lower-case alphanumeric words of ``text`` ("NPS AUV II" -> {"nps", "auv", "ii"})."""
    return set(re.findall(r"[a-z0-9]+", str(text).lower()))


#: How to make a track declare the vessel it is of (the advice of :func:`check_vessel`).
_REVESSEL = (
    "re-convert it with 'bayesid convert --vessel {vid}' (or --vessel your_ship.toml), or edit its "
    "'# vessel:' line to say {vid}"
)


def track_vessel(track: Track) -> str | None:
    """The vessel a track says it is of: ``meta["vessel"]`` (dataset readers) or the first
    ``vessel: ...`` comment line of its file, else None.

    Parameters
    ----------
    track : Track
        The track; its ``meta["vessel"]`` and ``meta["comments"]`` are read.

    Returns
    -------
    str or None
        The declared vessel, as written; None when the track declares none.
    """
    if track.meta.get("vessel"):
        return str(track.meta["vessel"])
    for c in track.meta.get("comments", []):
        m = re.match(r"\s*vessel\s*[:=]\s*(.+)", str(c), re.IGNORECASE)
        if m and m.group(1).strip():
            return m.group(1).strip()
    return None


def check_vessel(track: Track, vehicle, where: str | None = None) -> list[str]:
    """Compare a track's declared vessel (:func:`track_vessel`) with the vehicle it is fitted to.

    A vessel line that names another packaged vehicle (:data:`PACKAGED_VESSELS`) and not this
    one is an error; a vessel line that shares no word of three or more characters with the
    vehicle's id or name (generic words such as "model" aside) is a warning (it may be the same hull under another name).

    Parameters
    ----------
    track : Track
        The track.
    vehicle : Vehicle or Ship or None
        The vessel description it is fitted to (its ``id`` and ``display_name`` are compared);
        None skips the check.
    where : str, optional
        The file named in messages; default the track's name.

    Returns
    -------
    list of str
        The warnings (empty when the track declares no vessel or its vessel matches).

    Raises
    ------
    ValueError
        When the declared vessel is another packaged vehicle; the message names the file and
        both vessels.
    """
    declared = track_vessel(track)
    if declared is None or vehicle is None:
        return []
    name = where or track.name
    vid = str(vehicle.id)
    own = {
        w
        for w in _words(" ".join([vid.replace("_", " "), vid, vehicle.display_name]))
        if len(w) >= 3 and not w.isdigit() and w not in _GENERIC
    } | set(PACKAGED_VESSELS.get(vid, ()))
    said = _words(declared)
    others = [k for k, keys in PACKAGED_VESSELS.items() if k != vid and said & set(keys)]
    if others and not said & own:
        raise ValueError(
            f"{name}: the track's vessel line says {declared!r}, which is the packaged vehicle "
            f"{others[0]!r}, but the vehicle is {vid!r}. If the track is of {others[0]}, use --vehicle "
            f"{others[0]}; if it is of {vid}, {_REVESSEL.format(vid=vid)}"
        )
    if not said & own:
        return [
            f"{name}: the track's vessel line says {declared!r}; the vehicle is {vid!r} (no word in common: "
            f"a track of another vessel?); if it is of {vid}, {_REVESSEL.format(vid=vid)}"
        ]
    return []


def _check_heading(track: Track, refuse) -> None:
    """The unit checks of the heading (against the yaw rate r when logged): ``refuse(column,
    message)`` raises for a heading, yaw rate or clock in the wrong unit."""
    t = track.t
    psi = np.asarray(track["psi"], float)
    fin = psi[np.isfinite(psi)]
    jumps = np.abs(np.diff(fin))
    # the heading's rate over the yaw rate r: the clock's unit when the heading is in rad,
    # the heading's or r's unit otherwise
    k = None
    if "r" in track:
        dpsi = np.gradient(np.unwrap(np.where(np.isfinite(psi), psi, 0.0)), t)
        k = _ratio(dpsi, track["r"])
    if k is not None and np.max(np.abs(fin)) <= 2 * math.pi + 0.1:
        for f, unit in TIME_UNITS:
            if abs(k / f - 1.0) < 0.15:
                refuse(
                    "t",
                    f"the heading turns {k:.3g} x as fast per time unit as the yaw rate r says: time looks like {unit}",
                )
    if k is not None and 20.0 < k < 150.0:
        refuse("psi", f"its rate is {k:.3g} x the yaw rate r: heading looks like degrees")
    if k is not None and 1 / 150.0 < k < 1 / 20.0:
        refuse("r", f"the heading's rate is {k:.3g} x r: yaw rate looks like deg/s")
    if np.max(np.abs(fin)) > 2 * math.pi + 0.1 and np.max(np.abs(fin)) <= 361.0 and (jumps > 300.0).any():
        refuse("psi", f"values up to {np.max(np.abs(fin)):.4g} wrapping by 360: heading looks like degrees")
    if np.median(jumps) > 0.5:
        refuse("psi", f"it changes by {np.median(jumps):.3g} per sample (median): heading looks like degrees")
    if np.max(np.abs(fin)) > 2 * math.pi + 0.1:
        ok = np.isfinite(psi)
        rate = np.abs(np.diff(psi[ok]) / np.diff(t[ok]))
        if rate.size and np.percentile(rate, 95) > 1.0:
            refuse(
                "psi",
                f"values up to {np.max(np.abs(fin)):.4g} turning at {np.percentile(rate, 95):.3g} "
                "units/s (95th percentile; no vessel turns at 1 rad/s): heading looks like degrees",
            )


#: Rudder sign evidence (|t| of the rudder's gain in the yaw-rate regression, the samples'
#: correlation discounted, :func:`rudder_response`) above which a rudder that turns the vessel the
#: other way is refused, and above which (down to 3) it is a warning.
RUDDER_SIGN_T = 6.0
#: Smallest rudder spread (rad, sd) for the sign check to say anything.
RUDDER_SPREAD = math.radians(1.0)


def rudder_response(track: Track, smooth_s: float = 2.0) -> dict | None:
    """Which way the rudder turns the vessel in a track: the gain ``b`` of the rudder angle in a
    first-order yaw-rate regression ``dr/dt = a r + b delta_r + c`` (Nomoto 1957; the heading
    smoothed and differentiated by a Savitzky-Golay filter over ``smooth_s``).

    In the package's convention (SNAME: a positive rudder angle, trailing edge to port, turns the
    vessel to port, ``r < 0``) ``b`` is negative; a log in the MMG papers' convention (+ =
    starboard) gives a positive ``b``.

    Parameters
    ----------
    track : Track
        A track with ``psi`` (rad) and ``delta_r`` (rad).
    smooth_s : float, default 2.0
        The filter's span, s (at least 7 samples).

    Returns
    -------
    dict or None
        ``b`` (1/s^2), ``t`` (its t statistic, discounted for the samples' correlation: one
        independent sample per ``smooth_s``) and ``n`` (samples); None without a heading and
        rudder, with fewer than 30 finite samples or a rudder spread below
        :data:`RUDDER_SPREAD`.
    """
    from scipy.signal import savgol_filter

    if "psi" not in track or "delta_r" not in track:
        return None
    t = np.asarray(track.t, float)
    psi, dr = np.asarray(track["psi"], float), np.asarray(track["delta_r"], float)
    ok = np.isfinite(psi) & np.isfinite(dr)
    if ok.sum() < 30 or np.std(dr[ok]) < RUDDER_SPREAD:
        return None
    h = float(np.median(np.diff(t[ok])))
    if not h > 0:
        return None
    grid = np.arange(t[ok][0], t[ok][-1], h)
    if grid.size < 30:
        return None
    psi_g = np.interp(grid, t[ok], np.unwrap(psi[ok]))
    dr_g = np.interp(grid, t[ok], dr[ok])
    w = max(7, int(round(smooth_s / h)) | 1)
    if w >= grid.size:
        return None
    r = savgol_filter(psi_g, w, 3, deriv=1, delta=h)
    rdot = savgol_filter(psi_g, w, 3, deriv=2, delta=h)
    n_eff = max(grid.size * h / max(smooth_s, w * h), 4.0)
    b, tb = _gain(np.column_stack([r, dr_g, np.ones_like(r)]), rdot, grid.size / n_eff)
    k, tk = _gain(np.column_stack([dr_g, np.ones_like(r)]), r, grid.size / n_eff, at=0)
    return {"b": b, "t": tb, "K": k, "t_K": tk, "n": int(grid.size)}


def _gain(X: np.ndarray, y: np.ndarray, inflation: float, at: int = 1) -> tuple[float, float]:
    """Least-squares coefficient ``at`` of ``y ~ X`` and its t statistic with the variance
    multiplied by ``inflation`` (correlated samples)."""
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - X @ coef
    cov = np.linalg.pinv(X.T @ X) * float(res @ res) / max(len(y) - X.shape[1], 1)
    se = math.sqrt(max(cov[at, at] * inflation, 1e-300))
    return float(coef[at]), float(coef[at] / se)


#: Median |course over ground - heading| (deg) within which a reading of the heading fits the
#: track (:func:`heading_course`), when the other reading is 20 deg further off: a vessel's drift
#: angle stays below it over most of a run (KVLCC2's 35 deg turning circle: 26 deg).
HEADING_COURSE_DEG = 45.0
#: Above this median |course over ground - heading (+ drift angle)| (deg), a heading that turns
#: with the track is warned about: an offset between the heading and the positions (a magnetic
#: heading, a heading relative to the start, a sensor's mounting), or a vessel going astern or
#: sideways without u, v logged. The largest over the real runs (1-20 Hz, u and v dropped at
#: 1 Hz) but one: 28.5 deg (a low-speed Esso Osaka run at 1 Hz); that one, going astern, 60 deg;
#: a simulated KVLCC2 35 deg turning circle 26 deg.
HEADING_OFFSET_DEG = 40.0
#: Share of the turns (the heading changing by more than 5 deg over a baseline) in which the
#: course over ground turns the same way, below which the heading is refused as turning the other
#: way (counted counterclockwise, or a mathematical angle): each of the 48 real HSVA and Esso Osaka
#: runs (at 20, 10 and 1 Hz) turns the same way in 0.83 of its turns or more, each with its heading
#: negated in 0.04 or fewer.
TURN_AGREEMENT = 0.2


def _noise_sd2(y) -> float:
    """A signal's sample noise, robustly, from its second differences (1.4826 MAD / sqrt 6; the
    first estimate of :func:`bayesid.protocol.estimate_noise`, which this layer does not import:
    in a coarse log it reads some of the motion too, which the checks here allow for)."""
    d = np.diff(np.asarray(y, float), 2)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(6.0)) if d.size > 2 else 0.0


def heading_course(track: Track, baseline_s: float = 5.0) -> dict | None:
    """How the heading agrees with the course over ground (the direction of travel along a chord,
    ``atan2(dy, dx)``: from north, clockwise, in the package's north-east-down frame; the chord the
    shortest baseline over which the vessel moves 50 times the positions' noise, at most
    ``baseline_s``): whether they turn the same way, and the median absolute difference (deg)
    between the course and the heading along each chord (circular mean), read three ways: as logged (``psi``
    clockwise from north; plus the drift angle ``atan2(v, u)`` when the track logs ``u`` and
    ``v``: a vessel going astern or sideways), counterclockwise (``-psi``) and as a mathematical
    angle from the x axis (``pi/2 - psi``). Only baselines along which the vessel moves (a
    displacement above half the median one and ten times the positions' noise) count.

    Parameters
    ----------
    track : Track
        With ``x``, ``y`` (m) and ``psi`` (rad).
    baseline_s : float, default 5.0
        Baseline of the course, s.

    Returns
    -------
    dict or None
        ``as_logged``, ``counterclockwise``, ``from_x_axis`` (deg), ``n`` (baselines used),
        ``turn_agreement`` (share of the turns, chords ``baseline_s`` apart over which the heading
        changes by more than 5 deg, in which the course turns the same way; None with
        fewer than 10 turns, or turns of more than 60 deg per baseline, median: a clock in other
        units) and ``n_turns``; None without the columns or fewer than 10 moving baselines.
    """
    if any(k not in track for k in ("x", "y", "psi")):
        return None
    t = np.asarray(track.t, float)
    x, y, psi = (np.asarray(track[k], float) for k in ("x", "y", "psi"))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(psi)
    if ok.sum() < 20:
        return None
    t, x, y, psi = t[ok], x[ok], y[ok], psi[ok]
    h = float(np.median(np.diff(t)))
    if not h > 0:
        return None
    noise = math.hypot(_noise_sd2(x), _noise_sd2(y))
    step = float(np.median(np.hypot(np.diff(x), np.diff(y))))
    # the shortest baseline whose chord is 50 x the positions' noise (the course to about 1.6 deg), at most
    # baseline_s: a longer chord lags the heading and aliases a fast zigzag's turns (REMUS 100's 7 s period)
    k_noise = int(math.ceil(50.0 * noise / step)) if step > 0 else t.size
    k = max(1, min(k_noise, int(round(baseline_s / h)), t.size // 4))
    dx, dy = x[k:] - x[:-k], y[k:] - y[:-k]
    dist = np.hypot(dx, dy)
    moving = dist > max(10.0 * noise, 0.5 * float(np.median(dist)))
    if moving.sum() < 10:
        return None

    def along(angle):
        """The circular mean of an angle over each chord's samples."""
        c = np.concatenate([[0.0], np.cumsum(np.exp(1j * angle))])
        return np.angle(c[k + 1 :] - c[: -k - 1])

    course_all = np.arctan2(dy, dx)
    head_all = along(psi)
    course, head = course_all[moving], head_all[moving]
    drift = 0.0
    if "u" in track and "v" in track:
        u, v = (np.asarray(track[c], float)[ok] for c in ("u", "v"))
        b = np.arctan2(v, u)
        b = along(np.where(np.isfinite(b), b, 0.0))[moving]
        drift = b
    course_sd = math.sqrt(2.0) * noise / max(float(np.median(dist[moving])), 1e-12)

    def wrap(a):
        return np.angle(np.exp(1j * a))

    def med(a):
        return float(np.degrees(np.median(np.abs(wrap(a)))))

    # the turns: chords baseline_s apart (both short: course and heading at the same instants, so the
    # drift angle alone tells them apart), both moving, over which the heading changes by more than 5 deg
    # and three times the course's noise
    m = max(k, min(int(round(baseline_s / h)), t.size // 4))
    both = moving[:-m] & moving[m:] if moving.size > m else np.zeros(0, bool)
    dc = wrap(course_all[m:] - course_all[:-m])[both]
    dh = wrap(head_all[m:] - head_all[:-m])[both]
    turning = np.abs(dh) > max(math.radians(5.0), 3.0 * course_sd)
    # a baseline over which the heading typically turns by more than 60 deg (a clock in other units)
    # aliases the course's turns: no verdict
    judged = turning.sum() >= 10 and float(np.median(np.abs(dh[turning]))) < math.radians(60.0)
    agree = float(np.mean(np.sign(dc[turning]) == np.sign(dh[turning]))) if judged else None
    return {
        "as_logged": med(course - head - drift),
        "counterclockwise": med(course + head),
        "from_x_axis": med(course - (math.pi / 2 - head)),
        "n": int(moving.sum()),
        "turn_agreement": agree,
        "n_turns": int(turning.sum()),
    }


def _check_heading_course(track: Track, refuse, warn: list, name: str) -> None:
    """Refuse a heading that turns the other way from the course over ground
    (:func:`heading_course`, :data:`TURN_AGREEMENT`), naming the reading that fits; warn of an
    offset between a heading that turns with the track and the course
    (:data:`HEADING_OFFSET_DEG`)."""
    got = heading_course(track)
    if got is None:
        return
    frame = (
        "the package's frame is north-east-down: x north, y east, psi clockwise from north (from x towards y), "
        "the course over ground atan2(dy, dx)"
    )
    agree = got["turn_agreement"]
    if agree is not None and agree < TURN_AGREEMENT:
        ccw, fx = got["counterclockwise"], got["from_x_axis"]
        if fx <= HEADING_COURSE_DEG and ccw - fx >= 20.0:
            how = (
                f"it is measured from the other axis (|course - (pi/2 - psi)| {got['from_x_axis']:.0f} deg, median): "
                "a mathematical angle from x, or x and y swapped (x east, y north): use psi' = pi/2 - psi and "
                "r' = -r, or swap x and y"
            )
        elif ccw <= HEADING_COURSE_DEG and fx - ccw >= 20.0:
            how = f"|course + psi| {got['counterclockwise']:.0f} deg (median): negate psi and r"
        else:
            how = "with an offset besides: negate psi and r, then check the offset"
        refuse(
            "psi",
            f"the heading turns the other way from the course over ground (in {1 - agree:.0%} of "
            f"{got['n_turns']} turns of 5 s): it is counted counterclockwise; {how}; {frame}",
        )
    if got["as_logged"] > HEADING_OFFSET_DEG:
        warn.append(
            f"{name}: column 'psi': the heading differs from the course over ground by a median "
            f"{got['as_logged']:.0f} deg over {got['n']} baselines of 5 s (a vessel's drift angle is smaller over "
            "most of a run): an offset (a magnetic or relative heading, a sensor's mounting) or a vessel going astern "
            "or sideways (with u and v logged the check allows for the drift angle)? " + frame
        )


def _check_rudder_sign(track: Track, refuse, warn: list, name: str) -> None:
    """Refuse (or warn about) a rudder that turns the vessel the other way than the package's
    convention says (:func:`rudder_response`): both the yaw-rate gain and the steady gain
    positive, their t statistics summing to more than :data:`RUDDER_SIGN_T` (3 for a warning)."""
    resp = rudder_response(track)
    if resp is None or not (resp["t"] > 0 and resp["t_K"] > 0):
        return
    msg = (
        f"a positive rudder angle turns the vessel to starboard in this run (yaw-rate gain t = {resp['t']:.1f}, "
        f"steady turn-rate gain t = {resp['t_K']:.1f}), while the package's convention is + = to port (SNAME); "
        "if the log uses + = to starboard (MMG papers), put the line '# rudder positive: starboard' before its "
        "header (delta_r is then negated on reading); if instead its heading alone is counted counterclockwise, "
        "negate psi and r (on a run along the x axis the course over ground cannot tell); if its x, y, psi are "
        "in a frame that turns the "
        "other way (x east, y north, psi counterclockwise from x: the heading then agrees with the course over "
        "ground and only the turns are mirrored), convert them to the package's north-east-down frame (x north, "
        "y east, psi clockwise from north: swap x and y, psi' = pi/2 - psi, r' = -r)"
    )
    if resp["t"] + resp["t_K"] > RUDDER_SIGN_T:
        refuse("delta_r", msg)
    if resp["t"] + resp["t_K"] > 3.0:
        warn.append(f"{name}: column 'delta_r': {msg}")


#: A track's ``|delta_r|`` may pass the vehicle's rudder limit by this much (deg) without a warning
#: (a rudder sensor's offset and noise; the Esso Osaka runs stop at 35.3 deg against a 35 deg gear).
RUDDER_LIMIT_MARGIN_DEG = 1.0


def rudder_limit_deg(vehicle) -> float | None:
    """The vehicle's largest rudder angle either side.

    Parameters
    ----------
    vehicle : Vehicle or Ship or None
        A submarine (its ``limits.rudder_max``, rad) or a ship (its file's ``[limits]
        rudder_max_deg``).

    Returns
    -------
    float or None
        Deg; None when a ship file has no ``[limits]``, or without a vehicle.
    """
    limits = getattr(vehicle, "limits", None)
    if limits is not None:
        return math.degrees(limits.rudder_max)
    return getattr(vehicle, "rudder_max_deg", None)


def _check_rudder_limit(track: Track, vehicle, name: str) -> list[str]:
    """A warning when the track's ``|delta_r|`` passes the vehicle's rudder limit
    (:func:`rudder_limit_deg`) by more than :data:`RUDDER_LIMIT_MARGIN_DEG`: not a refusal, since
    a log may hold a steering gear's overshoot, but a track of another vessel, or a rudder in
    another scale, shows the same way."""
    limit = rudder_limit_deg(vehicle)
    if limit is None or "delta_r" not in track:
        return []
    deg = np.degrees(np.abs(np.asarray(track["delta_r"], float)))
    over = np.flatnonzero(np.nan_to_num(deg, nan=0.0) > limit + RUDDER_LIMIT_MARGIN_DEG)
    if not over.size:
        return []
    t, k = track.t, over[np.argmax(deg[over])]
    file = getattr(vehicle, "file_path", "")
    source = f"[limits] rudder_max_deg of {file}" if file else "[limits] rudder_max_deg"
    return [
        f"{name}: column 'delta_r': |delta_r| reaches {deg[k]:.3g} deg ({math.radians(deg[k]):.4g} rad, "
        f"t = {clock(t[k])} s), beyond the rudder limit of {vehicle.id} ({limit:g} deg, {source}) in {over.size} "
        f"sample(s) from t = {clock(t[over[0]])} to {clock(t[over[-1]])} s: a steering gear overshoot, or a track of "
        "another vessel?"
    ]


#: A rudder ramp may move this much (deg) between two log samples (the 90th percentile over the
#: ramps' samples) before the log is too coarse for the rudder's rate. Held between samples (the
#: fits' default ``--inputs hold``), the model's rudder acts on average half an interval late: on
#: synthetic zigzags with a 16 deg/s rudder that put coefficients several sds off at 1-5 Hz (3.2
#: deg and more per sample) and much less at 10-20 Hz (``benchmarks/log_rate_coverage.py``,
#: ``reports/benchmark_log_rate.txt``). The HSVA KVLCC2 logs move 0.8 deg per sample at 20 Hz.
RUDDER_STEP_DEG = 2.0


#: Lone rudder jumps (more than :data:`RUDDER_STEP_DEG` within one sample interval, outside a ramp)
#: a run may hold before the log's timing is warned: a turn's execute and a pull-out's return are
#: one or two; a closed-loop zigzag reverses at every check angle.
LONE_JUMPS_WARNED = 3


def _rudder_changes(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The per-sample changes of ``d`` (deg) and which of them lie inside ramps: runs of at least
    two consecutive changes of more than 0.05 deg in the same direction."""
    step = np.diff(d)
    moving = np.isfinite(step) & (np.abs(step) > 0.05)
    sign = np.sign(step) * moving
    same_next = np.zeros(step.size, bool)
    same_next[:-1] = (sign[:-1] != 0) & (sign[:-1] == sign[1:])
    in_ramp = same_next.copy()
    in_ramp[1:] |= same_next[:-1]
    return step, in_ramp


def _check_log_rate(track: Track, name: str) -> list[str]:
    """Warnings when the log is coarse for the rudder: its ramps move more than
    :data:`RUDDER_STEP_DEG` between samples (the 90th percentile), or it jumps by more than that
    within single intervals, outside a ramp, :data:`LONE_JUMPS_WARNED` times or more (a closed-loop
    manoeuvre's reversals, whose times within the interval no reading of the log knows)."""
    if "delta_r" not in track or track.t.size < 4:
        return []
    step, in_ramp = _rudder_changes(np.degrees(np.asarray(track["delta_r"], float)))
    h = float(np.median(np.diff(track.t)))
    out = []
    ramps = np.abs(step[in_ramp])
    p90 = float(np.percentile(ramps, 90)) if ramps.size >= 4 else 0.0
    if p90 > RUDDER_STEP_DEG:
        out.append(
            f"{name}: column 'delta_r': the rudder's ramps move {p90:.2g} deg between samples (90th percentile; log "
            f"interval {h:.3g} s, about {p90 / h:.3g} deg/s): the log is coarse for the rudder's rate. Held between "
            f"samples (--inputs hold, the default) the model's rudder acts on average {h / 2:.2g} s late, which moved "
            "fitted coefficients beyond their intervals on synthetic logs at 1-5 Hz (reports/benchmark_log_rate.txt); "
            "read it with --inputs rate (the gear's rate: --rudder-rate or the ship file's [service] rudder_rate_deg_s; "
            "bayesid fit and diagnose; discover and design read the rudder as the fit of --model did) or --inputs "
            "linear, or log the rudder faster (or the column logs the rudder order, not its angle)"
        )
    lone = np.abs(step[~in_ramp & np.isfinite(step)])
    lone = lone[lone > RUDDER_STEP_DEG]
    if lone.size >= LONE_JUMPS_WARNED:
        out.append(
            f"{name}: column 'delta_r': the rudder jumps {lone.size} times by up to {lone.max():.3g} deg within one "
            f"sample interval ({h:.3g} s), not along a ramp: an actuator faster than the log, or the column logs the "
            "rudder order (then the surface followed it at its gear's rate: a submarine's 'actuator' effect fits that "
            "servo). Where a jump fell between two samples (a closed-loop zigzag's reversals do) no --inputs "
            f"reading knows its time within the {h:.3g} s, and that timing alone can move the fitted coefficients far "
            "beyond their intervals (reports/benchmark_reversal_timing.txt): fit with --inputs rate --retime (the "
            "gear's rate, --rudder-rate, or a rate far above the jumps' for an instant actuator), which estimates "
            "their times with the coefficients, or log the rudder angle as it moves"
        )
    return out


def _check_pieces(track: Track, name: str) -> list[str]:
    """A warning naming the gaps that split a track into continuous pieces
    (:func:`bayesid.data.track.continuous_pieces`: no x, y or psi, or no sample, for more than
    five sample intervals): every command fits and scores each piece on its own (no window crosses
    a gap, and a piece too short for a window is left out), which a user reading the scores should
    know."""
    if any(k not in track or not np.isfinite(np.asarray(track[k], float)).any() for k in ("x", "y", "psi")):
        return []
    pieces = continuous_pieces(track)
    if len(pieces) < 2:
        return []
    t = track.t
    gaps = []
    for (_, end), (start, _) in zip(pieces[:-1], pieces[1:]):
        i, j = int(np.searchsorted(t, end)), int(np.searchsorted(t, start))
        gaps.append(f"t = {clock(end)}-{clock(start)} s ({start - end:.3g} s, {_rows(track, i, j)})")
    shown = "; ".join(gaps[:3]) + (f"; and {len(gaps) - 3} more" if len(gaps) > 3 else "")
    return [
        f"{name}: {len(gaps)} gap{'s' if len(gaps) > 1 else ''} in x, y, psi or the inputs ({shown}): the run is "
        f"fitted and scored as {len(pieces)} continuous pieces, no window crosses a gap, and a piece shorter than "
        "one window (after the start estimate's span) is left out; a clock jump shows here too"
    ]


def check_track(track: Track, vehicle=None, where: str | None = None) -> list[str]:
    """Units and plausibility of a track (module docstring).

    Parameters
    ----------
    track : Track
        The track to check.
    vehicle : Vehicle or Ship, optional
        The vessel description it will be fitted to (its declared vessel, nominal rpm, rudder
        limit (a warning when ``|delta_r|`` passes it by more than
        :data:`RUDDER_LIMIT_MARGIN_DEG`) and its own plausibility checks,
        :meth:`~bayesid.data.vehicle.Vehicle.track_warnings`); None skips those checks. Whatever
        the vehicle, a rudder whose ramps move more than :data:`RUDDER_STEP_DEG` between samples
        is a warning (the log is coarse for the inputs held between samples), and so is one that
        jumps by more than that within single intervals :data:`LONE_JUMPS_WARNED` times or more
        (reversals whose times between the samples no fit knows), and so are gaps that split the
        track into continuous pieces (:func:`_check_pieces`).
    where : str, optional
        The file named in messages; default the track's name.

    Returns
    -------
    list of str
        The warnings (empty when nothing looks odd).

    Raises
    ------
    ValueError
        A column in the wrong unit, naming file, column and the unit it looks like; a rudder
        that turns the vessel against the sign convention (:func:`rudder_response`); a hole in
        a logged input (:func:`input_gaps`); or a
        declared vessel that is another packaged vehicle (:func:`check_vessel`).
    """
    name = where or track.name
    warn = check_vessel(track, vehicle, where)
    input_gaps(track, name)
    t = track.t
    if t.size < 3:
        return warn
    h = float(np.median(np.diff(t)))

    def refuse(col, msg):
        raise ValueError(
            f"{name}: column '{col}': {msg}; the track contract is SI with angles in rad, rpm for n "
            "(README, Track files)"
        )

    for col in ("delta_r", "delta_s", "delta_b"):
        if col in track:
            m = float(np.nanmax(np.abs(track[col]))) if np.isfinite(track[col]).any() else 0.0
            if m > math.pi / 2 + 1e-6:
                refuse(col, f"values up to {m:.4g} cannot be a control-surface angle in rad; it looks like degrees")
    if track.meta.get("psi_wraps"):
        warn.append(
            f"{name}: column 'psi': the heading was wrapped like a compass's ({track.meta['psi_wraps']} wrap(s) of "
            "2 pi): unwrapped on reading"
        )
    warn += _check_rudder_limit(track, vehicle, name)
    warn += _check_log_rate(track, name)
    warn += _check_pieces(track, name)
    ground = None
    if "x" in track and "y" in track:
        # over a 5 s baseline, so that position noise does not pass for speed
        k = max(1, min(int(round(5.0 / h)), t.size // 4)) if h > 0 else 1
        dx, dy = track["x"][k:] - track["x"][:-k], track["y"][k:] - track["y"][:-k]
        sp = np.hypot(dx, dy) / (t[k:] - t[:-k])
        sp = sp[np.isfinite(sp)]
        if sp.size:
            ground = float(np.median(sp))
            if h >= 10.0 and 0.1 <= 1000.0 * ground <= 30.0 and ground < 0.05:
                refuse(
                    "t",
                    f"median sample interval {h:.4g} with positions moving {ground:.3g} units per "
                    "interval-unit: it looks like milliseconds",
                )
    body = None
    if "u" in track and np.isfinite(track["u"]).any():
        body = float(np.nanmedian(np.hypot(track["u"], track["v"]) if "v" in track else np.abs(track["u"])))
    if ground is not None and body is not None and body > 0.05 and ground > 0:
        # positions moving f x faster per time unit than u says (milliseconds aside: a ratio of
        # 1/1000 is positions in km as well; the heading rate below, or the sample interval
        # above, tells those apart)
        for f, unit in TIME_UNITS[:2]:
            if abs(ground / body / f - 1.0) < 0.15:
                refuse(
                    "t",
                    f"the positions move {ground / body:.3g} x as fast per time unit as the body speed "
                    f"u, v: time looks like {unit}",
                )
    if "psi" in track and np.isfinite(track["psi"]).sum() > 10:
        _check_heading(track, refuse)
    if ground is not None and ground > 0.05 and body is not None:
        k = body / ground
        for f, unit in SPEED_UNITS:
            if abs(k / f - 1.0) < 0.15:
                refuse("u", f"body speed is {k:.3g} x the speed from the positions: u, v look like {unit}")
    if ground is not None and ground > 0 and body is not None and body > 0.05:
        k = body / ground
        for f, unit in POSITION_UNITS:
            if abs(k / f - 1.0) < 0.15:
                refuse("x", f"the positions move {1 / k:.3g} x as fast as the body speed u, v: x, y look like {unit}")
    if "wind_dir" in track and np.isfinite(track["wind_dir"]).any():
        m = float(np.nanmax(np.abs(track["wind_dir"])))
        if m > 2 * math.pi + 0.1:
            refuse("wind_dir", f"values up to {m:.4g} cannot be a direction in rad; it looks like degrees")
    # the conventions, once the units passed (_check_heading has refused a heading in degrees): the heading
    # against the course over ground first (a heading counted the other way would otherwise read as a rudder
    # of the other sign)
    if "psi" in track and np.isfinite(track["psi"]).sum() > 10:
        _check_heading_course(track, refuse, warn, name)
    _check_rudder_sign(track, refuse, warn, name)
    if "n" in track and np.isfinite(track["n"]).any():
        n_med = float(np.nanmedian(track["n"]))
        ahead = body if body is not None else ground
        if n_med < 0 and ahead is not None and ahead > 0.05:
            warn.append(
                f"{name}: column 'n': propeller speed is negative (median {n_med:.4g} rpm, astern) while "
                f"the vessel moves at {ahead:.3g} m/s: sign convention (n > 0 ahead)?"
            )
    if vehicle is not None:  # what the vessel itself makes implausible (planes on a ship, speed)
        warn += vehicle.track_warnings(track, name, body, ground)
    nominal_rpm = (vehicle.nominal_rpm or 0.0) if vehicle is not None else 0.0
    if "n" in track:
        n = np.asarray(track["n"], float)
        n = n[np.isfinite(n)]
        moving = body if body is not None else ground
        if n.size and not np.any(n) and moving is not None and moving > MOVING_SPEED:
            warn.append(
                f"{name}: column 'n': propeller speed is 0 rpm in every row while the vessel moves at "
                f"{moving:.3g} m/s (median): a propeller speed that was not logged? The model will see "
                "no thrust; give the logged rpm (or leave the run out)"
            )
        elif n.size and not np.any(n):
            warn.append(f"{name}: column 'n': propeller speed is 0 in every row (drifting or not logged?)")
        elif n.size and nominal_rpm > 0 and np.max(np.abs(n)) < nominal_rpm / 20.0:
            refuse(
                "n",
                f"values up to {np.max(np.abs(n)):.4g} against the vehicle's nominal {nominal_rpm:g} rpm: "
                "it looks like rev/s",
            )
    return warn


__all__ = [
    "BayesidWarning",
    "TrackWarning",
    "check_track",
    "check_vessel",
    "rudder_response",
    "RUDDER_SIGN_T",
    "RUDDER_SPREAD",
    "RUDDER_LIMIT_MARGIN_DEG",
    "rudder_limit_deg",
    "input_gaps",
    "track_vessel",
    "SPEED_UNITS",
    "POSITION_UNITS",
    "TIME_UNITS",
    "PACKAGED_VESSELS",
    "HOLE_INTERVALS",
    "MOVING_SPEED",
]
