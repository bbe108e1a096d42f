"""Manoeuvre runs of any simulation model: the approach condition of a set of logged runs, the
standard manoeuvres' input schedules from it, and their free runs (no restarts), a zigzag steered
closed loop on each parameter row's own heading.

These are what a designed run (:mod:`bayesid.analysis.gap.design`) and a predicted standard
manoeuvre are made of, for a submarine (:mod:`bayesid.models.submarine`) and a ship
(:mod:`bayesid.models.ship`) alike: every function takes a :class:`~bayesid.models.SimulationModel`
and parameter rows, and simulates the rows together (one batched simulation per pass).

The package's one vocabulary of manoeuvre kinds is :data:`MANOEUVRE_KINDS`: what ``bayesid
simulate`` runs, what the ship trials (:mod:`bayesid.models.ship.trials`) and the design's menu
(:data:`KINDS`, the runs :func:`open_loop_inputs` schedules) are, and what
:func:`bayesid.estimation.indices.manoeuvre_kind` reads a logged run as. Older and shorter names
(``turn``, ``pull-out``) are accepted where a user names a kind (:func:`canonical_kind`).
Procedures: ITTC Recommended Procedure 7.5-04-02-01 (2017), "Full Scale Manoeuvring Trials",
Sec. 2.2.1 (turning circle), 2.2.2 (zigzag), 2.2.4 (spiral), 2.2.6 (pull-out).

Sign convention: the package's rudder is positive to port; ``side="port"`` is a positive first
rudder angle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..data.track import STATE_NAMES, Track
from ..data.validate import BayesidWarning

__all__ = [
    "KINDS",
    "MANOEUVRE_KINDS",
    "KIND_ALIASES",
    "canonical_kind",
    "Approach",
    "ManoeuvreRun",
    "approach_condition",
    "run_approach",
    "approach_row",
    "with_rpm_scaled",
    "training_points",
    "PropulsionPointWarning",
    "APPROACH_TOLERANCE",
    "APPROACH_UNSTEADY",
    "APPROACH_OTHER_SPEED",
    "APPROACH_UNDER_WAY",
    "other_speed_note",
    "rudder_rate",
    "menu",
    "ramp",
    "open_loop_inputs",
    "input_track",
    "simulate_run",
    "simulate_runs",
    "zigzag_rudders",
    "run_inputs",
    "free_run_states",
]

#: The manoeuvre kinds of the package, one name each (ITTC 7.5-04-02-01 Sec. 2.2):
#: ``turning_circle``, ``zigzag``, ``pull_out``; ``spiral`` (the spiral test: a ship's
#: direct/reverse spiral, a submarine's inward spiral of Furlong's paper); ``spiral_steps`` (the
#: design's short spiral: five rudder steps from one side through zero to the other);
#: ``speed_change``, ``prbs`` (a pseudo-random rudder sequence); ``straight``.
MANOEUVRE_KINDS = (
    "turning_circle",
    "zigzag",
    "pull_out",
    "spiral",
    "spiral_steps",
    "speed_change",
    "prbs",
    "straight",
)
#: Other names a user may give for a kind of :data:`MANOEUVRE_KINDS` (``bayesid simulate
#: --manoeuvre turn`` before the vocabulary was one).
KIND_ALIASES = {"turn": "turning_circle", "turning-circle": "turning_circle", "pull-out": "pull_out"}
#: The runs :func:`open_loop_inputs` schedules (a zigzag's switches by :func:`zigzag_rudders`).
KINDS = ("turning_circle", "pull_out", "zigzag", "spiral_steps", "speed_change", "prbs")
#: A run is at another propulsion point than others when, at its logged approach rpm, a model's
#: steady speed misses its approach speed by more than this share beyond what it misses on the
#: others (:func:`approach_row`).
APPROACH_TOLERANCE = 0.03
#: An approach whose speed changes by more than this share over the samples read is not at equilibrium, and
#: is not judged.
APPROACH_UNSTEADY = 0.02
#: A run whose approach speed is off the model's steady speed at its rpm by more than this share is
#: not under way at that rpm (starting from rest with the propeller just ordered, or stopping), so
#: its approach says nothing of its propulsion point and is not judged (a basin's point differs by
#: a few tens of per cent at most).
APPROACH_UNDER_WAY = 0.5
#: Runs whose approach speeds differ by more than this share are not at one speed: a miss of the
#: model's resistance or thrust curve at one of the speeds explains a difference of their
#: propulsion points as well (:func:`other_speed_note`).
APPROACH_OTHER_SPEED = 0.10
#: Time of the first order from the start of a run, s.
T_EXECUTE = 5.0


@dataclass(frozen=True)
class Approach:
    """The approach condition a run starts from (:func:`approach_condition`).

    Parameters
    ----------
    u : float
        Speed ahead, m/s (the run starts straight ahead at it).
    rpm : float
        Propeller speed, rpm.
    rudder_rate : float
        How fast the rudder moves to an order, rad/s (``math.inf``: it steps).
    duration_s : float
        The runs' length, s (the training runs' median).
    """

    u: float
    rpm: float
    rudder_rate: float
    duration_s: float


@dataclass(frozen=True)
class ManoeuvreRun:
    """One run of the menu.

    Parameters
    ----------
    kind : str
        ``"turning_circle"``, ``"pull_out"``, ``"zigzag"``, ``"spiral_steps"``,
        ``"speed_change"`` or ``"prbs"``.
    rudder_deg : float
        Rudder angle (zigzag, turn, pull-out; the steps' largest; the PRBS amplitude), deg.
    check_deg : float or None
        A zigzag's check heading change, deg.
    side : str
        ``"port"`` or ``"starboard"`` (the first rudder's; ``"-"`` for a speed change).
    rpm : float
        Propeller rpm after the execute.
    duration_s : float
        Length, s.
    execute_s : float, default :data:`T_EXECUTE`
        Time of the first order from the start of the run, s.
    """

    kind: str
    rudder_deg: float
    check_deg: float | None
    side: str
    rpm: float
    duration_s: float
    execute_s: float = T_EXECUTE

    @property
    def name(self) -> str:
        """A short label, e.g. ``zigzag 20/20 port``."""
        if self.kind == "zigzag":
            return f"zigzag {self.rudder_deg:g}/{self.check_deg:g} {self.side}"
        if self.kind == "speed_change":
            return f"speed change to {self.rpm:.0f} rpm"
        return f"{self.kind.replace('_', ' ')} {self.rudder_deg:g} deg {self.side}"


def rudder_rate(tracks: list) -> float | None:
    """How fast the runs' rudder moves when it moves: the median of |d delta_r / dt| over the
    sample intervals where it changes faster than 1 deg/s and than three times a log's jitter
    (its noise sd from the median absolute second difference, whose median a held or slewing
    rudder leaves at 0, times sqrt 2 over the interval). A rudder held between orders moves in few
    intervals: a percentile over all of them is the held rudder's 0 (a step-logged rudder's
    designed runs then ramped at 1 deg/s); a step order logged at 5 Hz reads as the jump over one
    interval, as fast as the log can say.

    Parameters
    ----------
    tracks : list of Track
        Runs with ``delta_r`` (rad; non-finite samples skipped).

    Returns
    -------
    float or None
        rad/s; None when the rudder never moves.
    """
    moving = []
    for tr in tracks:
        t, d = np.asarray(tr.t, float), np.asarray(tr["delta_r"], float)
        ok = np.isfinite(d)
        if ok.sum() < 4:
            continue
        t, d = t[ok], d[ok]
        rate = np.abs(np.diff(d) / np.diff(t))
        noise_sd = 1.4826 * float(np.median(np.abs(np.diff(d, 2)))) / math.sqrt(6.0)
        jitter = math.sqrt(2.0) * noise_sd / float(np.median(np.diff(t)))
        moving.append(rate[rate > max(math.radians(1.0), 3.0 * jitter)])
    r = np.concatenate(moving) if moving else np.zeros(0)
    return float(np.median(r)) if r.size else None


def approach_condition(tracks: list) -> Approach:
    """The approach condition of logged runs, the one a predicted or designed run starts from:
    the median over the runs of each run's speed over its first 5 s (the median of ``u`` when
    logged, else the slope of a straight line through the positions: differences of noisy
    positions would read the noise as speed) and rpm, the rudder rate the runs' rudder moves at
    (:func:`rudder_rate`, at least 1 deg/s; 5 deg/s when the rudder never moves) and the median
    run length.

    Parameters
    ----------
    tracks : list of Track
        The runs (``delta_r``, ``n``; ``u`` or ``x, y`` for the speed).

    Returns
    -------
    Approach
        ``u`` (m/s), ``rpm``, ``rudder_rate`` (rad/s), ``duration_s``.

    Raises
    ------
    ValueError
        No run logs the propeller speed ``n``.
    """
    if not any("n" in tr for tr in tracks):
        raise ValueError("approach_condition: no track logs the propeller speed n")
    us, ns, lens = [], [], []
    for tr in tracks:
        t = np.asarray(tr.t, float)
        first = t <= t[0] + 5.0
        if "u" in tr and np.isfinite(np.asarray(tr["u"], float)[first]).any():
            us.append(float(np.nanmedian(np.asarray(tr["u"], float)[first])))
        elif "x" in tr and "y" in tr:
            x, y = np.asarray(tr["x"], float)[first], np.asarray(tr["y"], float)[first]
            ok = np.isfinite(x) & np.isfinite(y)
            if ok.sum() > 2:
                us.append(float(np.hypot(*np.polyfit(t[first][ok], np.column_stack([x[ok], y[ok]]), 1)[0])))
        if "n" in tr:
            ns.append(float(np.nanmedian(np.asarray(tr["n"], float)[first])))
        lens.append(t[-1] - t[0])
    rate = rudder_rate(tracks)
    rate = math.radians(5.0) if rate is None else rate
    return Approach(
        u=float(np.median(us)) if us else 1.0,
        rpm=float(np.median(ns)),
        rudder_rate=max(rate, math.radians(1.0)),
        duration_s=float(np.median(lens)),
    )


def run_approach(track, max_s: float = 10.0, min_s: float = 2.0, rudder_tol_deg: float = 1.0) -> dict | None:
    """One run's own approach: the samples from its start until the rudder first leaves its
    first value by more than ``rudder_tol_deg`` (at most ``max_s``; at least ``min_s``: a log
    that starts at the execute, as the SIMMAN HSVA runs do, is read over its first ``min_s``, in
    which a ship's speed has barely changed), their speed (the median of ``u`` when logged, else
    the slope of a straight line through the positions, as :func:`approach_condition`), their
    propeller speed and how fast the speed changes there.

    Parameters
    ----------
    track : Track
        The run (``t``, ``delta_r``, ``n``; ``u`` or ``x, y``).
    max_s, min_s : float, default 10.0, 2.0
        Longest and shortest approach read, s.
    rudder_tol_deg : float, default 1.0
        Rudder movement that ends the approach, deg.

    Returns
    -------
    dict or None
        ``seconds``, ``speed_m_s``, ``rpm`` (median of ``n``), ``accel_m_s2`` (slope of the
        logged ``u``, or the along-track acceleration of a quadratic through the positions),
        ``rudder_moved`` (the rudder left its first value within
        the ``min_s`` read); None when the run has no ``n`` or ``delta_r`` column or is shorter
        than ``min_s``.
    """
    if "n" not in track or "delta_r" not in track:
        return None
    t = np.asarray(track.t, float)
    d = np.asarray(track["delta_r"], float)
    ok = np.isfinite(d)
    if not ok.any():
        return None
    d0 = d[ok][0]
    moved = np.flatnonzero(ok & (np.abs(d - d0) > math.radians(rudder_tol_deg)))
    t_end = min(t[0] + max_s, t[moved[0]] if moved.size else t[-1])
    rudder_moved = bool(t_end - t[0] < min_s)
    t_end = max(t_end, t[0] + min_s)
    if t[-1] < t_end:
        return None
    seg = t <= t_end
    n = np.asarray(track["n"], float)[seg]
    if not np.isfinite(n).any():
        return None
    accel, speed = None, None
    if "u" in track and np.isfinite(np.asarray(track["u"], float)[seg]).sum() > 2:
        u = np.asarray(track["u"], float)[seg]
        good = np.isfinite(u)
        speed = float(np.median(u[good]))
        accel = float(np.polyfit(t[seg][good], u[good], 1)[0])
    elif "x" in track and "y" in track:
        x, y = np.asarray(track["x"], float)[seg], np.asarray(track["y"], float)[seg]
        good = np.isfinite(x) & np.isfinite(y)
        if good.sum() > 3:
            ts = t[seg][good]
            xy = np.column_stack([x[good], y[good]])
            speed = float(np.hypot(*np.polyfit(ts, xy, 1)[0]))
            c2, c1, _ = np.polyfit(ts - ts.mean(), xy, 2)  # the along-track acceleration at the middle
            accel = float(2.0 * (c1 @ c2) / max(float(np.hypot(*c1)), 1e-9))
    if speed is None:
        return None
    return {
        "seconds": float(t_end - t[0]),
        "speed_m_s": speed,
        "rpm": float(np.nanmedian(n)),
        "accel_m_s2": accel,
        "rudder_moved": rudder_moved,
    }


def approach_row(model, p, track, matched: bool = False) -> dict | None:
    """One run's propulsion point against the model's: its own approach
    (:func:`run_approach`) and the speed the model at ``p`` settles at with
    the rpm the run logs there (``model.steady_speed``).

    Parameters
    ----------
    model : SimulationModel
        A model with ``steady_speed`` (a ship's).
    p : array_like, shape (n_params,)
        Its parameters.
    track : Track
        The run.
    matched : bool, default False
        Also ``matched_rpm``: the rpm the model needs for the run's approach speed
        (``model.self_propulsion_rpm``; None when it has no equilibrium there).

    Returns
    -------
    dict or None
        ``run``, the :func:`run_approach` reading, ``model_speed_m_s``, ``speed_error`` (model /
        measured - 1) and ``steady`` (the speed changes by at most
        :data:`APPROACH_UNSTEADY` over the samples read, and the run is under way at its rpm:
        ``|speed_error| <=`` :data:`APPROACH_UNDER_WAY`); None when the run has
        no approach to read, is not moving ahead, or the model has no equilibrium at its rpm.
    """
    a = run_approach(track)
    if a is None or a["rpm"] <= 0 or a["speed_m_s"] <= 0:
        return None
    try:
        ms = float(model.steady_speed(p, a["rpm"]))
    except ValueError:
        return None
    acc, err = a["accel_m_s2"], ms / a["speed_m_s"] - 1.0
    settled = acc is None or abs(acc) * a["seconds"] <= APPROACH_UNSTEADY * a["speed_m_s"]
    steady = settled and abs(err) <= APPROACH_UNDER_WAY
    row = {"run": track.name, **a, "model_speed_m_s": ms, "speed_error": err, "steady": bool(steady)}
    if matched:
        try:
            row["matched_rpm"] = float(model.self_propulsion_rpm(p, a["speed_m_s"]))
        except ValueError:
            row["matched_rpm"] = None
    return row


def with_rpm_scaled(track, factor: float):
    """A copy of a run with its propeller speed ``n`` scaled by ``factor`` (driving it at another
    propulsion point, :func:`approach_row`'s ``matched_rpm`` over its logged rpm).

    Parameters
    ----------
    track : Track
        The run (with ``n``).
    factor : float
        The scale of ``n``.

    Returns
    -------
    Track
        The copy (name, units and metadata kept).
    """
    data = dict(track.data, n=np.asarray(track["n"], float) * factor)
    return Track(track.t, data, name=track.name, units=dict(track.units), meta=dict(track.meta))


class PropulsionPointWarning(BayesidWarning):
    """Training runs at different propulsion points (:func:`training_points`): one propeller
    model holds them all, so the fit compromises between them."""


def training_points(model, p, tracks) -> dict | None:
    """Whether the training runs share one propulsion point: each steady approach's
    :func:`approach_row` under the fitted model, and the runs whose ``speed_error`` is more than
    :data:`APPROACH_TOLERANCE` from the median of them all (runs from another basin, model,
    propeller or rpm control among the others: the fit's one propeller model compromises between
    them, and every run's speed carries it).

    Parameters
    ----------
    model : SimulationModel
        The fitted model (one without ``steady_speed`` gives None).
    p : array_like, shape (n_params,)
        Its parameters.
    tracks : list of Track
        The training runs.

    Returns
    -------
    dict or None
        ``runs`` (the rows, each with ``apart``), ``median_error``, ``apart`` (the names) and
        ``sentence``; None when fewer than two runs have a steady approach or the model has no
        ``steady_speed``.
    """
    if getattr(model, "steady_speed", None) is None:
        return None
    rows = [r for r in (approach_row(model, p, tr) for tr in tracks) if r is not None]
    steady = [r["speed_error"] for r in rows if r["steady"]]
    if len(steady) < 2:
        return None
    med = float(np.median(steady))
    for r in rows:
        r["apart"] = bool(r["steady"] and abs(r["speed_error"] - med) > APPROACH_TOLERANCE)
    apart = [r["run"] for r in rows if r["apart"]]
    sentence = ""
    if apart:
        errs = ", ".join(f"{r['run']} {r['speed_error']:+.1%}" for r in rows if r["apart"])
        sentence = (
            f"training run(s) {', '.join(apart)} are at another propulsion point than the others: at the rpm each "
            f"logs on its approach the fitted model settles off its approach speed by {errs}, against a median of "
            f"{med:+.1%} (another basin, model, propeller or rpm control). One propeller model holds them all, so "
            "the fit compromises between them and every run's speed in the turns carries it: fit those runs apart, "
            "or leave them out"
        )
        ref = [r["speed_m_s"] for r in rows if r["steady"] and not r["apart"]]
        sentence += other_speed_note([r["speed_m_s"] for r in rows if r["apart"]], ref)
    return {"runs": rows, "median_error": med, "apart": apart, "sentence": sentence}


def other_speed_note(speeds, reference) -> str:
    """The other explanation of runs at another propulsion point when they are not at the others'
    speed: the model's resistance or thrust curve missing one of the speeds.

    Parameters
    ----------
    speeds : sequence of float
        The approach speeds of the runs at another point, m/s.
    reference : sequence of float
        The approach speeds of the runs they are compared with, m/s.

    Returns
    -------
    str
        ``"; ..."`` when some speed differs from the reference median by more than
        :data:`APPROACH_OTHER_SPEED`, else empty.
    """
    if not len(speeds) or not len(reference):
        return ""
    u0 = float(np.median(reference))
    if u0 <= 0 or max(abs(u / u0 - 1.0) for u in speeds) <= APPROACH_OTHER_SPEED:
        return ""
    return (
        f"; but their approach speeds ({', '.join(f'{u:.3g}' for u in speeds)} m/s) are not the others' "
        f"({u0:.3g} m/s), so a resistance or thrust curve the model misses at one of the speeds explains the "
        "difference as well"
    )


def canonical_kind(name: str, known=MANOEUVRE_KINDS, what: str = "manoeuvre") -> str:
    """The name of :data:`MANOEUVRE_KINDS` a user's manoeuvre name stands for (itself, or the kind
    of :data:`KIND_ALIASES`).

    Parameters
    ----------
    name : str
        A kind or an alias (``"turn"``, ``"pull-out"``).
    known : tuple of str, default :data:`MANOEUVRE_KINDS`
        The kinds accepted here (a subset where a caller runs only some).
    what : str, default "manoeuvre"
        Names the caller's vocabulary in the error.

    Returns
    -------
    str
        The kind.

    Raises
    ------
    ValueError
        A name that is no kind of ``known`` nor an alias of one, listing the names accepted.
    """
    kind = KIND_ALIASES.get(name, name)
    if kind not in known:
        names = list(known) + [a for a, k in KIND_ALIASES.items() if k in known]
        raise ValueError(f"unknown {what} {name!r}; known: {', '.join(names)}")
    return kind


def menu(approach: Approach, max_rudder_deg: float = 35.0, duration_s: float | None = None) -> list[ManoeuvreRun]:
    """The standard manoeuvres a design compares (:func:`bayesid.analysis.gap.design.design`):
    turning circles both sides at the largest and at half the rudder, pull-outs, zigzags 10/10,
    20/20 and at the largest rudder both sides, a spiral's rudder steps, a speed change to 60 %
    of the rpm and a pseudo-random rudder sequence, all from ``approach``.

    Parameters
    ----------
    approach : Approach
        :func:`approach_condition`.
    max_rudder_deg : float, default 35.0
        The largest rudder of every run, deg (the vehicle's limit where that is smaller:
        :func:`bayesid.analysis.gap.design.within_limits`).
    duration_s : float, optional
        Length of every run, s (default: the approach's, at least 90 s).

    Returns
    -------
    list of ManoeuvreRun
        The candidate runs, each with its inputs and a description.
    """
    big = float(max_rudder_deg)
    D = float(duration_s or max(90.0, approach.duration_s))
    rpm = approach.rpm
    runs = []
    for side in ("port", "starboard"):
        runs += [
            ManoeuvreRun("turning_circle", big, None, side, rpm, D),
            ManoeuvreRun("turning_circle", round(big / 2), None, side, rpm, D),
            ManoeuvreRun("pull_out", min(20.0, big), None, side, rpm, D),
        ]
        # the zigzags 10/10 and 20/20 and at the largest rudder, each once (a 20 deg limit: two)
        runs += [ManoeuvreRun("zigzag", a, a, side, rpm, D) for a in sorted({min(10.0, big), min(20.0, big), big})]
    runs += [
        ManoeuvreRun("spiral_steps", round(big * 0.7), None, "port", rpm, D),
        ManoeuvreRun("speed_change", 0.0, None, "-", 0.6 * rpm, D),
        ManoeuvreRun("prbs", round(big / 2), None, "port", rpm, D),
    ]
    return runs


def ramp(t: np.ndarray, orders: list, rate: float) -> np.ndarray:
    """A rudder angle that moves at ``rate`` to each ordered angle from its time on, from 0:
    piecewise linear between the orders' breakpoints (an order that comes before the rudder got
    to the last one turns it round where it is).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times, s.
    orders : list of (float, float)
        ``[(time s, angle rad), ...]``, in time order.
    rate : float
        Rudder rate, rad/s.

    Returns
    -------
    ndarray, shape (n,)
        Rudder angle, rad.
    """
    knots_t, knots_v = [float(t[0])], [0.0]
    for i, (t_o, target) in enumerate(orders):
        t_next = orders[i + 1][0] if i + 1 < len(orders) else float(t[-1]) + 1.0
        t_o = max(float(t_o), knots_t[-1])
        v0 = float(np.interp(t_o, knots_t, knots_v)) if t_o <= knots_t[-1] else knots_v[-1]
        knots_t.append(t_o)
        knots_v.append(v0)
        t_reach = t_o + abs(target - v0) / rate
        if t_reach <= t_next:
            knots_t.append(t_reach)
            knots_v.append(float(target))
        else:  # the next order comes before the rudder gets there
            knots_t.append(t_next)
            knots_v.append(v0 + np.sign(target - v0) * rate * (t_next - t_o))
    return np.interp(t, knots_t, knots_v)


def open_loop_inputs(run: ManoeuvreRun, approach: Approach, t: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """The open-loop rudder and rpm of a run from :data:`T_EXECUTE` (a zigzag's first order only;
    :func:`zigzag_rudders` adds the switches). Port is a positive rudder angle.

    Parameters
    ----------
    run : ManoeuvreRun
        The run.
    approach : Approach
        ``rpm`` before the execute, ``rudder_rate``.
    t : ndarray, shape (n,)
        Times from the start of the run, s.
    rng : numpy.random.Generator or None
        The pseudo-random sequence's signs (``prbs`` only).

    Returns
    -------
    delta_r : ndarray, shape (n,)
        Rudder angle, rad.
    n : ndarray, shape (n,)
        Propeller speed, rpm.
    """
    sgn = 1.0 if run.side == "port" else -1.0
    a = math.radians(run.rudder_deg) * sgn
    t0, D = run.execute_s, run.duration_s
    n = np.full_like(t, approach.rpm)
    if run.kind in ("turning_circle", "zigzag"):
        orders = [(t0, a)]
    elif run.kind == "pull_out":
        orders = [(t0, a), (t0 + 0.45 * D, 0.0)]
    elif run.kind == "spiral_steps":
        steps = np.linspace(1.0, -1.0, 5) * a
        orders = [(t0 + i * (D - t0) / steps.size, float(s)) for i, s in enumerate(steps)]
    elif run.kind == "speed_change":
        orders, n = [], np.where(t >= t0, run.rpm, approach.rpm)
    else:  # prbs: a pseudo-random sign every hold time, the hold a tenth of the run
        hold = max(D / 10.0, 5.0)
        times = np.arange(t0, D, hold)
        orders = [(float(s), a * float(rng.choice((-1.0, 1.0)))) for s in times]
    return ramp(t, orders, approach.rudder_rate), n


def _track(t, delta, n, approach: Approach) -> Track:
    """An input-only track from the approach state (states as placeholders: the simulation
    starts from ``s0``)."""
    z = np.zeros_like(t)
    return Track(t, {"x": z, "y": z, "psi": z, "u": z + approach.u, "v": z, "r": z, "delta_r": delta, "n": n})


def simulate_run(model, p, inputs: Track, approach: Approach) -> Track | None:
    """A model's run through an input schedule from the approach state, in one window (no
    restarts): e.g. a designed run flown by a vehicle file's truth, for a synthetic check.

    Parameters
    ----------
    model : SimulationModel
        The model (:func:`bayesid.models.build_model`).
    p : array_like, shape (n_params,)
        Its parameter vector (e.g. ``model.start()``).
    inputs : Track
        The inputs ``delta_r`` (rad) and ``n`` (rpm) on its times (its states are not read).
    approach : Approach
        :func:`approach_condition` (or any object with ``u``): the run starts straight ahead at
        ``u`` m/s.

    Returns
    -------
    Track or None
        ``x y psi u v r`` (m, rad, m/s, rad/s) and the inputs at the model's steps from the
        inputs' first time; None when the run diverges.
    """
    return simulate_runs(model, np.asarray(p, float)[None], [inputs], approach)[0]


def simulate_runs(model, P, inputs: list, approach: Approach) -> list:
    """:func:`simulate_run` for several parameter vectors at once, each through its own input
    schedule on the same times (one batched simulation: e.g. each parameter draw's own zigzag).

    Parameters
    ----------
    model : SimulationModel
        The model.
    P : array_like, shape (B, n_params)
        Parameter vectors.
    inputs : list of Track
        ``B`` input schedules on the same times, or one for every row.
    approach : Approach
        :func:`approach_condition`.

    Returns
    -------
    list of (Track or None)
        One per row, as :func:`simulate_run` returns it.

    Raises
    ------
    ValueError
        Neither one nor ``B`` input schedules.
    """
    ctx, S = _simulate(model, P, inputs, approach)
    out = []
    for b, Sb in enumerate(S):
        if not np.isfinite(Sb).all():
            out.append(None)
            continue
        u = inputs[b if len(inputs) > 1 else 0]
        data = {k: Sb[:, STATE_NAMES.index(k)] for k in ("x", "y", "psi", "u", "v", "r")}
        data.update(delta_r=np.interp(ctx.ts, u.t, u["delta_r"]), n=np.interp(ctx.ts, u.t, u["n"]))
        out.append(Track(np.asarray(ctx.ts, float), data))
    return out


def _simulate(model, P, inputs: list, approach: Approach):
    """The track context of ``inputs`` (each row its own schedule when there are several) and the
    states ``(B, n_steps, 12)`` of every row from the approach state."""
    P = np.atleast_2d(np.asarray(P, float))
    if len(inputs) not in (1, P.shape[0]):
        raise ValueError(f"{len(inputs)} input schedules for {P.shape[0]} parameter vectors (one, or one each)")
    s0 = np.zeros(12)
    s0[6] = approach.u
    ctx = model.context(inputs[0], None, s0=s0)
    if len(inputs) > 1:
        ctx = ctx.with_row_inputs(inputs)
    return ctx, model.simulate(ctx, P, measured_start=False)


def input_track(t, delta_r, n, approach: Approach) -> Track:
    """An input-only track for :func:`simulate_run` (the states are placeholders).

    Parameters
    ----------
    t : array_like, shape (n,)
        Times, s.
    delta_r : array_like, shape (n,)
        Rudder angle, rad.
    n : array_like, shape (n,)
        Propeller speed, rpm.
    approach : Approach
        :func:`approach_condition`.

    Returns
    -------
    Track
        The inputs on ``t``.
    """
    return _track(np.asarray(t, float), np.asarray(delta_r, float), np.asarray(n, float), approach)


def zigzag_rudders(model, P, run: ManoeuvreRun, approach: Approach, t: np.ndarray) -> np.ndarray:
    """Each parameter vector's own zigzag rudder, steered on its own heading: the rudder is
    reversed each time the heading change from the approach passes the check angle on the
    rudder's side (the sign of the heading change a rudder gives is read from the row's first
    response). Found in lock step: every pass simulates the rows still turning towards a check
    angle together (:func:`simulate_runs`) and reverses each row's rudder where its heading
    passes it (at the first sample past it).

    Parameters
    ----------
    model : SimulationModel
        The model.
    P : array_like, shape (B, n_params)
        Parameter vectors.
    run : ManoeuvreRun
        A zigzag (``rudder_deg``, ``check_deg``, ``side``).
    approach : Approach
        :func:`approach_condition` (``u``, ``rpm``, ``rudder_rate``).
    t : ndarray, shape (n,)
        Times from the start of the run, s.

    Returns
    -------
    ndarray, shape (B, n)
        Rudder angle, rad: reversed at every check angle the heading passes until the run's end;
        a row whose run diverges keeps the orders found before.
    """
    P = np.atleast_2d(np.asarray(P, float))
    a = math.radians(run.rudder_deg) * (1.0 if run.side == "port" else -1.0)
    check = math.radians(run.check_deg)
    orders = [[(run.execute_s, a)] for _ in P]
    n = np.full_like(t, approach.rpm)
    turn: list = [None] * len(P)
    live = list(range(len(P)))
    # every pass adds at most one reversal per row, each at a later sample than the row's last:
    # the search ends when no row's heading passes another check angle before the run's end
    # (at most one pass per sample; it stopped after 12 reversals before, and a longer run held
    # its last rudder from there on: a turn, not a zigzag)
    for _ in range(t.size):
        if not live:
            break
        tracks = [_track(t, ramp(t, orders[b], approach.rudder_rate), n, approach) for b in live]
        sims = simulate_runs(model, P[live], tracks, approach)
        still = []
        for b, sim in zip(live, sims):
            if sim is None:
                continue
            h = np.unwrap(np.asarray(sim["psi"], float))
            h = np.interp(t, sim.t, h - h[0])
            if turn[b] is None:  # which way a positive rudder turns this model
                late = h[t > run.execute_s]
                turn[b] = float(np.sign(late[np.argmax(np.abs(late))])) * np.sign(a) or 1.0
            t_last, target = orders[b][-1]
            want = turn[b] * np.sign(target) * check
            after = np.flatnonzero((t > t_last) & (np.sign(want) * (h - want) >= 0))
            if after.size:
                orders[b].append((float(t[after[0]]), -target))
                still.append(b)
        live = still
    return np.array([ramp(t, o, approach.rudder_rate) for o in orders])


def run_inputs(model, p, run: ManoeuvreRun, approach: Approach, rng=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The input schedule of a menu run, from the approach condition: the rudder moves at the
    approach's rudder rate; a zigzag's rudder is reversed where ``model``'s heading passes the
    check angle (:func:`zigzag_rudders`; a user steers the real run by its own heading instead).

    Parameters
    ----------
    model : SimulationModel
        The model that steers a zigzag (a design's: the kept term's).
    p : array_like, shape (n_params,)
        Its parameter vector.
    run : ManoeuvreRun
        The run (:func:`menu`).
    approach : Approach
        :func:`approach_condition`.
    rng : numpy.random.Generator, optional
        The pseudo-random rudder sequence's signs (default: seed 0).

    Returns
    -------
    t : ndarray, shape (n,)
        Times from the start of the run, s (0.1 s or the model's step, whichever is smaller).
    delta_r : ndarray, shape (n,)
        Rudder angle, rad (+ to port, the package's convention).
    n : ndarray, shape (n,)
        Propeller speed, rpm.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    t = np.arange(0.0, run.duration_s, min(0.1, model.dt))
    delta, n = open_loop_inputs(run, approach, t, rng)
    if run.kind == "zigzag":
        delta = zigzag_rudders(model, np.asarray(p, float)[None], run, approach, t)[0]
    return t, delta, n


def free_run_states(model, P, run: ManoeuvreRun, approach: Approach, t: np.ndarray):
    """Each parameter vector's free run of a standard manoeuvre from the approach condition, a
    zigzag on the row's own switches (:func:`zigzag_rudders`; one batched simulation per pass),
    as arrays, diverged rows included (non-finite): what a band over parameter draws and a
    figure of every draw's run read.

    Parameters
    ----------
    model : SimulationModel
        The model.
    P : array_like, shape (B, n_params)
        Parameter vectors.
    run : ManoeuvreRun
        The run (its ``duration_s`` is not read: ``t`` is the run's time).
    approach : Approach
        :func:`approach_condition` (``rudder_rate`` ``math.inf``: the rudder steps).
    t : ndarray, shape (n,)
        Times from the start of the run, s.

    Returns
    -------
    ts : ndarray, shape (n_steps,)
        The model's step times, s.
    S : ndarray, shape (B, n_steps, 12)
        States of every row (:data:`bayesid.data.track.STATE_NAMES`; SI units).
    delta_r : ndarray, shape (B, n_steps)
        Each row's rudder angle at the step times, rad.
    """
    inputs = _free_run_inputs(model, P, run, approach, t)
    ctx, S = _simulate(model, P, inputs, approach)
    idx = np.asarray(ctx.idx)
    delta = np.array([np.asarray(inputs[b if len(inputs) > 1 else 0]["delta_r"], float)[idx] for b in range(len(S))])
    return np.asarray(ctx.ts, float), S, delta


def _free_run_inputs(model, P, run: ManoeuvreRun, approach: Approach, t: np.ndarray) -> list:
    """The input tracks of :func:`free_run_states`: one, or one per row for a zigzag."""
    P = np.atleast_2d(np.asarray(P, float))
    delta, n = open_loop_inputs(run, approach, t, None)
    if run.kind == "zigzag":
        return [_track(t, d, n, approach) for d in zigzag_rudders(model, P, run, approach, t)]
    return [_track(t, delta, n, approach)]
