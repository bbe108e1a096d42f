"""The candidate effects of a surface ship (:data:`SHIP_CATALOGUE`): wind loads, current and
delay act in the MMG kernel through :meth:`~bayesid.models.effects.Effect.kernel`, the sensor lag
(:class:`bayesid.models.effects.SensorLag`) on the measurements.
"""

from __future__ import annotations

import numpy as np

from ..effects import Effect, SensorLag, delay_starts, drift_seed, drift_starts
from .dynamics import apparent_wind
from .layout import COEFFICIENT_INDEX, WIND


class ShipWind(Effect):
    """Wind loads from the measured true wind: the seven wind coefficients of the Fourier form
    are the effect's parameters (kernel parameters of the MMG model).

    Parameters
    ----------
    name, params : str, tuple of str
        Catalogue key and parameter names (the fields of :class:`~bayesid.models.effects.Effect`;
        the instance of :data:`SHIP_CATALOGUE` sets them all).
    lo, hi, start, scale : tuple of float
        Bounds, start values and typical sizes of the parameters.
    magnitudes, source, description : tuple of dict, str, str
        Benchmark levels, the reasoning behind the values, a one-line description.
    n_nuisance, nuisance_lo, nuisance_hi : int, float, float
        Per-track parameters and their bounds.
    mode, input_effect, exo_columns, signature, neutral, needs_columns : object
        The other fields of :class:`~bayesid.models.effects.Effect`.
    """

    def kernel(self, kp, q):
        kp["prm"][:, [COEFFICIENT_INDEX[k] for k in WIND]] = q

    def start_values(self, vehicle):
        if vehicle.wind_start:
            return np.array([vehicle.wind_start[k] for k in WIND])
        return np.asarray(self.start, float)

    def force_signature(self, m):
        track, pr = m["track"], m["particulars"]
        if "wind_speed" not in track or not pr["A_front"] + pr["A_lateral"] > 0:
            return None
        t = m["t"]
        va, g = apparent_wind(track, m["u"], m["v"], m["psi"], t)
        qa = 0.5 * pr["rho_air"] * va**2
        z = np.zeros(t.size)
        return [
            np.column_stack([qa * pr["A_front"] * np.cos(g), z, z]),
            np.column_stack([z, qa * pr["A_lateral"] * np.sin(g), z]),
            np.column_stack([z, z, qa * pr["A_lateral"] * pr["L"] * np.sin(g)]),
            np.column_stack([z, z, qa * pr["A_lateral"] * pr["L"] * np.sin(2 * g)]),
            np.column_stack([z, z, qa * pr["A_lateral"] * pr["L"] * np.sin(3 * g)]),
        ]


class ShipCurrent(Effect):
    """Uniform current (earth frame) in the MMG kernel: the hull moves through the water, the
    track over ground.

    Parameters
    ----------
    name, params : str, tuple of str
        Catalogue key and parameter names (the fields of :class:`~bayesid.models.effects.Effect`;
        the instance of :data:`SHIP_CATALOGUE` sets them all).
    lo, hi, start, scale : tuple of float
        Bounds, start values and typical sizes of the parameters.
    magnitudes, source, description : tuple of dict, str, str
        Benchmark levels, the reasoning behind the values, a one-line description.
    n_nuisance, nuisance_lo, nuisance_hi : int, float, float
        Per-track parameters and their bounds.
    mode, input_effect, exo_columns, signature, neutral, needs_columns : object
        The other fields of :class:`~bayesid.models.effects.Effect`.
    """

    def kernel(self, kp, q):
        kp["cur"] = np.ascontiguousarray(q)

    def diagnosis_seed(self, evidence):
        return drift_seed(evidence)

    def fit_starts(self, p, i, model, seed):
        return drift_starts(p, i, seed)

    def force_signature(self, m):
        # a current leaves the Coriolis term of the current velocity seen in the body frame
        mass, r, t = m["particulars"]["mass_kg"], m["r"], m["t"]
        c, s = np.cos(m["psi"]), np.sin(m["psi"])
        return [
            np.column_stack([mass * r * s, mass * r * c, np.zeros(t.size)]),
            np.column_stack([-mass * r * c, mass * r * s, np.zeros(t.size)]),
        ]


class ShipDelay(Effect):
    """Pure time delay of the logged rudder and propeller (the MMG kernel's inputs averaged over
    the delayed step).

    Parameters
    ----------
    name, params : str, tuple of str
        Catalogue key and parameter names (the fields of :class:`~bayesid.models.effects.Effect`;
        the instance of :data:`SHIP_CATALOGUE` sets them all).
    lo, hi, start, scale : tuple of float
        Bounds, start values and typical sizes of the parameters.
    magnitudes, source, description : tuple of dict, str, str
        Benchmark levels, the reasoning behind the values, a one-line description.
    n_nuisance, nuisance_lo, nuisance_hi : int, float, float
        Per-track parameters and their bounds.
    mode, input_effect, exo_columns, signature, neutral, needs_columns : object
        The other fields of :class:`~bayesid.models.effects.Effect`.
    """

    def kernel(self, kp, q):
        kp["delay"] = q[:, 0]

    def fit_starts(self, p, i, model, seed):
        return delay_starts(p, i)

    def force_signature(self, m):
        u = m["u"]
        return [np.column_stack([u * u * m["rudder_rate"]] * 3)]


#: Candidate effects of a surface ship.
SHIP_CATALOGUE = {
    "wind": ShipWind(
        "wind",
        WIND,
        (-2.0,) * 7,
        (2.0,) * 7,
        (-0.7, 0.0, -0.8, 0.0, -0.1, -0.05, 0.0),
        (0.3,) * 7,
        neutral=(0.0,) * 7,
        needs_columns=("wind_speed", "wind_dir"),
        description="wind loads from the measured true wind (Fourier form, 7 coefficients)",
        source="Fujiwara, Ueno & Nimura (1998), J. Soc. Naval Arch. Japan 183; windage areas from the "
        "particulars; start values typical of tankers (Isherwood 1972)",
    ),
    "current": ShipCurrent(
        "current",
        ("current_x_mps", "current_y_mps"),
        (-0.5, -0.5),
        (0.5, 0.5),
        (0.0, 0.0),
        (0.05, 0.05),
        neutral=(0.0, 0.0),
        description="uniform current: the hull moves through the water, the track over ground",
        source="kinematic relative-velocity model (Fossen 2011, Sec. 10.3); pond drift of a few cm/s",
    ),
    "delay": ShipDelay(
        "delay",
        ("delay_s",),
        (0.0,),
        (3.0,),
        (0.2,),
        (0.3,),
        neutral=(0.0,),
        description="pure time delay of the logged rudder and propeller",
        source="logging / actuator latency",
    ),
    "sensor_lag": SensorLag(
        "sensor_lag",
        ("lag_s", "skew_s"),
        (0.0, -3.0),
        (5.0, 3.0),
        (0.5, 0.0),
        (0.3, 0.3),
        neutral=(0.0, 0.0),
        description="sensor dynamics: first-order lag of logged u, v, r and a position time skew",
        source="velocities from GNSS position differences through a causal Kalman filter (Esso Osaka: about "
        "1 s); navigation and attitude on separate clocks",
    ),
}


def get_effect(name) -> Effect:
    """A ship catalogue effect by name.

    Parameters
    ----------
    name : str or Effect
        A key of :data:`SHIP_CATALOGUE`; an :class:`~bayesid.models.effects.Effect` passes
        through.

    Returns
    -------
    Effect
        The effect.

    Raises
    ------
    ValueError
        Naming an unknown effect.
    """
    if isinstance(name, Effect):
        return name
    try:
        return SHIP_CATALOGUE[name]
    except KeyError:
        raise ValueError(f"unknown ship effect {name!r}; the ship catalogue has {sorted(SHIP_CATALOGUE)}") from None


__all__ = ["SHIP_CATALOGUE", "get_effect", "ShipWind", "ShipCurrent", "ShipDelay"]
