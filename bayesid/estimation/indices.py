"""Standard manoeuvre indices of a track: zigzag overshoots, initial turning time and period,
turning-circle advance, transfer and tactical diameter (ITTC 7.5-04-02-01).

Pure functions over arrays of a run (time, position, heading, rudder): the measured run and every
prediction of it are reduced to the same indices by the same code.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["manoeuvre_indices"]


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


def manoeuvre_indices(t, x, y, psi, delta) -> dict:
    """Standard indices of a turning circle or a zigzag from a track (ITTC 7.5-04-02-01, 2002,
    "Full scale manoeuvring trials procedure", Sec. 2.2: definitions of the turning circle and
    zigzag tests), after deciding which manoeuvre the run is.

    The rudder is read as holds: runs beyond 3 deg on one side lasting at least 2 s (shorter
    counter-rudder blips are not reversals). Execute: the first hold's start.

    * **turning**: one hold (the rudder never reversed) during which the heading changes by at
      least 90 deg: ``advance_m`` (distance along the approach heading at 90 deg of heading
      change), ``transfer_m`` (normal to it, at 90 deg) and ``tactical_diameter_m`` (normal
      distance at 180 deg; NaN when the heading does not get there before the rudder returns);
    * **zigzag**: at least two reversals between holds of similar size (each within a factor of
      two of the first), the heading oscillating about the approach heading (never 90 deg away):
      ``first_overshoot_deg`` and ``second_overshoot_deg`` (heading beyond the switching heading
      after the 1st and 2nd reversal);
    * otherwise ``"other"`` with the ``reason``, and no index.

    Arrays (n,): t (s), x, y (m), psi (rad, any wrap), delta (rad). Returns a dict with ``kind``
    (``"turning"``, ``"zigzag"``, ``"other"``), ``execute_t_s`` and the indices or ``reason``.
    """
    t, x, y, delta = (np.asarray(a, float) for a in (t, x, y, delta))
    psi = np.unwrap(np.asarray(psi, float))
    holds = _rudder_holds(t, delta, math.radians(3.0), 2.0)
    if not holds:
        return {"kind": "other", "reason": "the rudder is never held beyond 3 deg for 2 s"}
    i0 = holds[0][1]
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
        out["kind"] = "turning"
        c, s = math.cos(psi[i0]), math.sin(psi[i0])
        along = c * (x - x[i0]) + s * (y - y[i0])
        normal = -s * (x - x[i0]) + c * (y - y[i0])
        for name, ang in (("90", math.pi / 2), ("180", math.pi)):
            k = np.flatnonzero(np.abs(h[a : b + 1]) >= ang)
            if k.size:
                j = a + k[0]
                if name == "90":
                    out["advance_m"] = float(along[j])
                    out["transfer_m"] = float(abs(normal[j]))
                else:
                    out["tactical_diameter_m"] = float(abs(normal[j]))
        for key in ("advance_m", "transfer_m", "tactical_diameter_m"):
            out.setdefault(key, float("nan"))
        return out
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
    out["kind"] = "zigzag"
    sw = [hd[1] for hd in holds[1:]]  # first sample of each hold after a reversal
    for name, k in (("first_overshoot_deg", 0), ("second_overshoot_deg", 1)):
        if k < len(sw):
            j = sw[k]
            end = sw[k + 1] if k + 1 < len(sw) else h.size
            going = np.sign(h[j] - h[max(j - 5, 0)]) or 1.0  # the heading keeps turning this way
            seg = h[j:end]
            ext = seg.max() - h[j] if going > 0 else h[j] - seg.min()
            out[name] = float(np.degrees(max(ext, 0.0)))
        else:
            out[name] = float("nan")
    return out
