"""The IMO criteria of ship manoeuvrability, read from manoeuvre indices at full scale.

Source: IMO Resolution MSC.137(76) (2002), "Standards for ship manoeuvrability", Sec. 5.3
(criteria) with the definitions of Sec. 4.2 and the explanatory notes MSC/Circ.1053 (2002):

* 5.3.1 turning ability: in the turning circle manoeuvre (35 deg rudder or the largest angle
  permissible at the test speed, Sec. 4.2.2) the advance should not exceed 4.5 L and the tactical
  diameter 5 L;
* 5.3.2 initial turning ability: with 10 deg rudder the ship should not have travelled more than
  2.5 L by the time the heading has changed by 10 deg from the original heading (read from the
  10/10 zigzag, MSC/Circ.1053);
* 5.3.3 yaw-checking and course-keeping: the first overshoot of the 10/10 zigzag should not exceed
  10 deg if L/V < 10 s, 20 deg if L/V >= 30 s and 5 + L/(2V) deg in between; its second overshoot
  25 deg, 40 deg and 17.5 + 0.75 L/V deg; the first overshoot of the 20/20 zigzag 25 deg (L in m,
  V in m/s: the test speed);
* 5.3.4 stopping ability: track reach of the full-astern stop at most 15 L (up to 20 L for large
  ships at the Administration's discretion). ``manoeuvre_indices`` reads no stopping test, so this
  criterion is always listed as not run.

The criteria are for the ship at full scale. A model test is brought there by Froude scaling with
the model scale ``lambda`` (full-scale length / model length): lengths scale with ``lambda``,
speeds and times with ``sqrt(lambda)``, angles not at all. The distance criteria are ratios to L
and the 20/20 limit is a fixed angle, so they hold at any scale; only the 10/10 limits depend on
L/V, which is ``sqrt(lambda)`` times its model-scale value. Without a scale those two limits are
not given (a model's L/V would set the wrong, usually the strictest, limit).

Pure functions over the dicts of :func:`bayesid.estimation.indices.manoeuvre_indices`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["CRITERIA", "TESTS", "imo_criteria", "imo_tests", "overshoot_limits"]

#: (key, MSC.137(76) section, what is limited, the standard manoeuvre, index key, limit or None
#: where it depends on L/V, unit of the limit: "L" ship lengths or "deg")
CRITERIA = (
    ("advance", "5.3.1", "advance", "turning", "advance_m", 4.5, "L"),
    ("tactical_diameter", "5.3.1", "tactical diameter", "turning", "tactical_diameter_m", 5.0, "L"),
    (
        "initial_turning",
        "5.3.2",
        "distance to turn 10 deg with 10 deg rudder",
        "initial_turning",
        "initial_turning_distance_m",
        2.5,
        "L",
    ),
    ("first_overshoot_10_10", "5.3.3.1", "first overshoot", "zigzag_10_10", "first_overshoot_deg", None, "deg"),
    ("second_overshoot_10_10", "5.3.3.2", "second overshoot", "zigzag_10_10", "second_overshoot_deg", None, "deg"),
    ("first_overshoot_20_20", "5.3.3.3", "first overshoot", "zigzag_20_20", "first_overshoot_deg", 25.0, "deg"),
    ("stopping_track_reach", "5.3.4", "track reach", "stopping", None, 15.0, "L"),
)
#: The standard manoeuvres, as the table names them.
TESTS = {
    "turning": "turning circle (35 deg or max. rudder)",
    "initial_turning": "10 deg rudder (10/10 zigzag or 10 deg turn)",
    "zigzag_10_10": "10/10 zigzag",
    "zigzag_20_20": "20/20 zigzag",
    "stopping": "full-astern stopping test",
}
#: A run is a standard manoeuvre when its rudder angle is within RUDDER_TOL_DEG of the test's and a
#: zigzag's check heading (the median heading change at its reversals) within CHECK_TOL_DEG of it:
#: a helmsman's or autopilot's order lags the nominal check angle by a few tenths of a degree
#: (HSVA's KVLCC2 10/10 zigzags reverse at 10.3-10.6 deg), while a 10/5 zigzag is 5 deg away.
RUDDER_TOL_DEG = 1.5
CHECK_TOL_DEG = 2.0


def overshoot_limits(l_over_v_s: float) -> tuple[float, float]:
    """The limits of the first and second overshoot of the 10/10 zigzag (MSC.137(76) Sec. 5.3.3.1
    and 5.3.3.2).

    Parameters
    ----------
    l_over_v_s : float
        L/V at full scale, s (ship length in m over the test speed in m/s).

    Returns
    -------
    tuple of float
        (first, second) overshoot limits, deg: (10, 25) below 10 s, (20, 40) from 30 s, and
        (5 + L/V / 2, 17.5 + 0.75 L/V) in between (continuous at both ends).

    Raises
    ------
    ValueError
        ``l_over_v_s`` not a positive finite number.
    """
    lv = float(l_over_v_s)
    if not math.isfinite(lv) or lv <= 0:
        raise ValueError(f"L/V = {l_over_v_s!r} s must be a positive finite number")
    if lv < 10.0:
        return 10.0, 25.0
    if lv >= 30.0:
        return 20.0, 40.0
    return 5.0 + 0.5 * lv, 17.5 + 0.75 * lv


def _near(value, target: float, tol: float) -> bool:
    return value is not None and math.isfinite(value) and abs(abs(value) - target) <= tol


def imo_tests(indices: dict, *, max_rudder_deg: float = 35.0) -> list[str]:
    """The standard manoeuvres of MSC.137(76) a run is (keys of :data:`TESTS`).

    Parameters
    ----------
    indices : dict
        A :func:`~bayesid.estimation.indices.manoeuvre_indices` result (``kind``,
        ``rudder_deg``, a zigzag's ``check_heading_deg``).
    max_rudder_deg : float, default 35.0
        The turning circle's rudder angle: 35 deg, or the largest angle permissible at the test
        speed when that is less (Sec. 4.2.2), deg.

    Returns
    -------
    list of str
        ``"turning"`` (a turn at ``max_rudder_deg`` or more, less :data:`RUDDER_TOL_DEG`),
        ``"zigzag_10_10"``, ``"zigzag_20_20"`` (rudder and check heading within
        :data:`RUDDER_TOL_DEG` and :data:`CHECK_TOL_DEG` of the test's), ``"initial_turning"``
        (a 10/10 zigzag or a 10 deg turn); empty for any other run.
    """
    kind, rudder = indices.get("kind"), indices.get("rudder_deg")
    out = []
    if kind == "turning":
        if rudder is not None and abs(rudder) >= max_rudder_deg - RUDDER_TOL_DEG:
            out.append("turning")
        if _near(rudder, 10.0, RUDDER_TOL_DEG):
            out.append("initial_turning")
    elif kind == "zigzag":
        checks = [abs(c) for c in indices.get("check_heading_deg") or [] if c is not None and math.isfinite(c)]
        check = float(np.median(checks)) if checks else None
        for angle in (10.0, 20.0):
            if _near(rudder, angle, RUDDER_TOL_DEG) and _near(check, angle, CHECK_TOL_DEG):
                out.append(f"zigzag_{angle:.0f}_{angle:.0f}")
        if "zigzag_10_10" in out:
            out.append("initial_turning")
    return out


def _manoeuvre(indices: dict) -> str:
    """The run's manoeuvre as the table names it (side from the sign of its first rudder order:
    + port)."""
    rudder = indices.get("rudder_deg") or 0.0
    side = "port" if rudder > 0 else "starboard"
    if indices.get("kind") == "turning":
        return f"{abs(rudder):.0f} deg turning circle to {side}"
    test = "zigzag_10_10" if "zigzag_10_10" in imo_tests(indices) else "zigzag_20_20"
    return f"{TESTS[test]}, {side} first"


def _row(crit, run, indices, ref, length_m: float, scale) -> dict:
    """One criterion on one run (``ref``: the run that sets its test speed)."""
    key, section, what, test, index, limit, unit = crit
    lam = 1.0 if scale is None else float(scale)
    row = {
        "criterion": key,
        "section": section,
        "what": what,
        "test": test,
        "run": run,
        "manoeuvre": _manoeuvre(ref),
        "full_scale": scale is not None,
    }
    raw = indices.get(index) if indices.get("kind") == ref.get("kind") else None
    value = float(raw) if raw is not None and math.isfinite(raw) else None
    if unit == "L":
        row.update(
            value=None if value is None else value * lam,
            value_L=None if value is None else value / length_m,
            limit=limit * length_m * lam,
            limit_L=limit,
            unit="m",
        )
    else:
        speed = ref.get("execute_speed_m_s")
        lv = length_m / speed if speed and math.isfinite(speed) and speed > 0 else None
        row["l_over_v_s"] = None if lv is None else lv * math.sqrt(lam)
        if limit is None and scale is not None and lv is not None:
            limit = overshoot_limits(row["l_over_v_s"])[0 if key.startswith("first") else 1]
        row.update(value=value, limit=limit, unit="deg")
    if value is None:
        row["result"] = "not reached"
    elif row["limit"] is None:
        row["result"] = "no limit"
    else:
        # "should not exceed": the limit itself passes (a relative 1e-12 absorbs the round-off of scaling)
        row["result"] = "pass" if row["value"] <= row["limit"] * (1 + 1e-12) else "fail"
    return row


def imo_criteria(
    indices: dict,
    *,
    length_m: float,
    scale: float | None = None,
    reference: dict | None = None,
    max_rudder_deg: float = 35.0,
) -> list[dict]:
    """The IMO MSC.137(76) Sec. 5.3 criteria table of a set of runs (module docstring for the
    criteria, their sources and the Froude scaling).

    Parameters
    ----------
    indices : dict
        ``{run name: manoeuvre_indices result}`` (model scale: the vessel file's metres and
        seconds).
    length_m : float
        The vessel file's length between perpendiculars L, m.
    scale : float, optional
        The model scale lambda (full-scale length / ``length_m``): distances are multiplied by
        it and L/V by its square root. None: the values are at the file's scale and the 10/10
        overshoot limits (which depend on L/V at full scale) are not given (``"no limit"``).
    reference : dict, optional
        ``{run name: manoeuvre_indices result}`` that decides which standard manoeuvre each run
        is and its test speed V (``execute_speed_m_s``), e.g. the measured runs when
        ``indices`` are predictions of them (a prediction's heading at the recorded reversals is
        not a check heading). Default: ``indices`` itself.
    max_rudder_deg : float, default 35.0
        The turning circle's rudder angle (:func:`imo_tests`), deg.

    Returns
    -------
    list of dict
        In :data:`CRITERIA` order, one row per criterion and run it applies to: ``criterion``,
        ``section``, ``what``, ``test``, ``run``, ``manoeuvre``, ``value`` and ``limit`` (m at
        full scale for a distance, with ``value_L`` and ``limit_L`` in ship lengths; deg for an
        overshoot, with ``l_over_v_s``), ``unit``, ``full_scale`` and ``result``: ``"pass"``
        (value <= limit), ``"fail"``, ``"not reached"`` (the run does not give the index, e.g.
        a turn whose heading never got to 180 deg, or a prediction that is not the same kind of
        manoeuvre) or ``"no limit"`` (10/10 overshoots without a scale, or without a test
        speed). A criterion no run applies to has one row with ``run`` None, ``value`` None and
        ``result`` ``"not run"``. Runs no criterion applies to are not in it.

    Raises
    ------
    ValueError
        ``length_m`` or ``scale`` not a positive finite number.
    """
    for name, v in (("length_m", length_m), ("scale", scale)):
        if v is not None and (isinstance(v, bool) or not math.isfinite(float(v)) or float(v) <= 0):
            raise ValueError(f"{name} = {v!r} must be a positive finite number")
    reference = indices if reference is None else reference
    tests = {run: imo_tests(reference.get(run, ind), max_rudder_deg=max_rudder_deg) for run, ind in indices.items()}
    rows = []
    for crit in CRITERIA:
        runs = [run for run in indices if crit[3] in tests[run]]
        rows += [
            _row(crit, run, indices[run], reference.get(run, indices[run]), float(length_m), scale) for run in runs
        ]
        if not runs:
            key, section, what, test, _, limit, unit = crit
            rows.append(
                {
                    "criterion": key,
                    "section": section,
                    "what": what,
                    "test": test,
                    "run": None,
                    "manoeuvre": TESTS[test],
                    "full_scale": scale is not None,
                    "value": None,
                    "limit": None
                    if limit is None
                    else (limit * float(length_m) * (scale or 1.0) if unit == "L" else limit),
                    **({"limit_L": limit} if unit == "L" else {}),
                    "unit": "m" if unit == "L" else "deg",
                    "result": "not run",
                }
            )
    return rows
