"""The candidate effects of a surface ship (:data:`SHIP_CATALOGUE`): wind loads, current and
delay act in the MMG kernel through :meth:`~bayesid.models.effects.Effect.kernel`, the sensor lag
(:class:`bayesid.models.effects.SensorLag`) on the measurements.

The surge and the propeller (issue 67: where a ship's turns fail, the speed ``u`` is the channel
missed most): the MMG 2015 wake in a turn (:class:`ShipWakeInTurn`, a model form in place of
``wP exp(-4 beta_P^2)``) and shifts of one MMG coefficient the base model holds at its captive-test
value (:class:`ShipCoefficientShift`): the rudder's resistance in a turn (``tR``), the thrust
deduction (``tP``), the propulsion point (the effective wake ``wP``: rpm against speed) and the hull
resistance (``Xuu = -R'0``). The hull's coupling terms in a hard turn: MMG 2015's coupling speed
in place of the package's (:class:`ShipCouplingSpeed`, a model form). A shift of a coefficient the base model fits is not identifiable: the
model refuses it (:class:`~bayesid.models.ship.model.ShipModel`) and
:func:`~bayesid.analysis.gap.diagnose.catalogue_candidates` leaves it out, saying why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..effects import Effect, SensorLag, delay_starts, drift_seed, drift_starts
from .dynamics import apparent_wind
from .layout import COEFFICIENT_INDEX, FORM_INDEX, WAKE_IN_TURN, WIND, coupling_rl_weight


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

    #: the ship file's coefficients the effect sets (a model cannot also fit them)
    sets = WIND

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


class ShipWakeInTurn(Effect):
    """The MMG 2015 wake in a turn in place of ``w_P = wP exp(-4 beta_P^2)``: the propeller's
    effective inflow ``1 - w_P = (1 - wP) (1 + (1 - exp(-C1 |beta_P|)) (C2 - 1))``, ``C2m`` in place
    of ``C2`` for ``beta_P < 0`` (Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol. 20:37-52, eq. 16;
    the kernels' form in :mod:`bayesid.models.ship`). A model form, not an added term: it does not
    nest the base model (``neutral`` None), and the diagnosis judges it on the held-out runs like
    any candidate. Its parameters are the ship file's ``C1``, ``C2``, ``C2m``
    (:data:`~bayesid.models.ship.layout.WAKE_IN_TURN`), which :meth:`vehicle_coefficients` writes.

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

    #: the ship file's coefficients the effect sets (a model cannot also fit them)
    sets = WAKE_IN_TURN

    def kernel(self, kp, q):
        kp["prm"][:, [COEFFICIENT_INDEX[k] for k in WAKE_IN_TURN]] = q

    def start_values(self, vehicle):
        c = vehicle.coefficients
        if c.get("C1", 0.0) > 0.0:  # the ship file's own wake in a turn
            return np.array([c[k] for k in WAKE_IN_TURN], float)
        return np.asarray(self.start, float)

    def vehicle_coefficients(self, q, vehicle) -> dict:
        """The ship file's coefficients of fitted parameters ``q``.

        Parameters
        ----------
        q : array_like, shape (3,)
            ``C1``, ``C2``, ``C2m``.
        vehicle : Ship
            The ship (unused: the parameters are the coefficients).

        Returns
        -------
        dict
            ``{"C1": ..., "C2": ..., "C2m": ...}``.
        """
        return {k: float(x) for k, x in zip(WAKE_IN_TURN, q)}


class ShipCouplingSpeed(Effect):
    """MMG 2015's coupling speed in place of the ship file's: the hull's coupling terms ``Yvvr``,
    ``Yvrr``, ``Nvvr``, ``Nvrr`` divided by ``sqrt(u^2 + v^2 + (1 - c) k (rL)^2)``, ``k`` the
    file's weight of ``(rL)^2`` (``[form] coupling_speed``: 1 for the package's ``"Ut"``), ``c`` the
    effect's one parameter. ``c = 0`` (``neutral``) is the file's form, ``c = 1`` MMG 2015's
    ``U = sqrt(u^2 + v^2)`` (Yasukawa & Yoshimura 2015, J. Mar. Sci. Technol. 20:37-52, eqs. 6-8:
    ``v'^2 r'`` and ``v' r'^2`` made dimensional by ``U^2``). In a 35 deg turn the package's form gives
    these terms 0.6-0.75 of MMG's and turns tighter (``benchmarks/shipmmg_turn.py``); zigzags hardly
    tell the two apart (``benchmarks/kvlcc2_hull_form.py``). A model form that nests the base model:
    the diagnosis judges it on the held-out runs like any candidate, and ``--write-vehicle`` writes
    the fitted form into the file's ``[form]`` section (:meth:`vehicle_form`).

    Parameters
    ----------
    name, params : str, tuple of str
        Catalogue key and parameter names (the fields of :class:`~bayesid.models.effects.Effect`;
        the instance of :data:`SHIP_CATALOGUE` sets them all).
    lo, hi, start, scale : tuple of float
        Bounds, start values and typical sizes of the parameter.
    magnitudes, source, description : tuple of dict, str, str
        Benchmark levels, the reasoning behind the values, a one-line description.
    n_nuisance, nuisance_lo, nuisance_hi : int, float, float
        Per-track parameters and their bounds.
    mode, input_effect, exo_columns, signature, neutral, needs_columns : object
        The other fields of :class:`~bayesid.models.effects.Effect`.
    """

    #: the ship file's coefficients the effect sets: none (the form is not a coefficient)
    sets = ()

    def kernel(self, kp, q):
        kp["prm"][:, FORM_INDEX["coupling_rL"]] *= 1.0 - q[:, 0]

    @staticmethod
    def unsupported(ship) -> str | None:
        """Why the effect cannot change ``ship``'s model, or None.

        Parameters
        ----------
        ship : Ship
            The ship.

        Returns
        -------
        str or None
            A ship whose coupling speed is already MMG's ``U``, or without coupling terms, says so
            (naming its id).
        """
        if coupling_rl_weight(ship.form.get("coupling_speed", "Ut")) == 0.0:
            return f"{ship.id}: its coupling speed is already MMG 2015's U ([form] coupling_speed)"
        if not any(ship.coefficients.get(k, 0.0) for k in ("Yvvr", "Yvrr", "Nvvr", "Nvrr")):
            return f"{ship.id}: no coupling term (Yvvr, Yvrr, Nvvr, Nvrr) in its coefficients"
        return None

    def vehicle_form(self, q, vehicle) -> dict:
        """The ship file's ``[form]`` choice of fitted ``q``.

        Parameters
        ----------
        q : array_like, shape (1,)
            ``c``, MMG's share of the coupling speed.
        vehicle : Ship
            The ship: its own weight of ``(rL)^2``.

        Returns
        -------
        dict
            ``{"coupling_speed": "U"}`` at ``c = 1``, ``"Ut"`` at a weight of 1, else the weight.
        """
        w = coupling_rl_weight(vehicle.form.get("coupling_speed", "Ut")) * (1.0 - float(q[0]))
        return {"coupling_speed": "U" if w <= 0.0 else "Ut" if w >= 1.0 else round(w, 4)}


@dataclass(frozen=True, eq=False)
class ShipCoefficientShift(Effect):
    """A shift of one MMG coefficient that the base model holds at its captive-test (or file)
    value: the kernel's coefficient is the file's plus the effect's one parameter, 0 (``neutral``)
    leaving the base model. Refused by the model when the coefficient is free
    (:class:`~bayesid.models.ship.model.ShipModel`).

    Parameters
    ----------
    name, params : str, tuple of str
        Catalogue key and parameter names (the fields of :class:`~bayesid.models.effects.Effect`;
        the instances of :data:`SHIP_CATALOGUE` set them all).
    lo, hi, start, scale : tuple of float
        Bounds, start values and typical sizes of the shift.
    magnitudes, source, description : tuple of dict, str, str
        Benchmark levels, the reasoning behind the values, a one-line description.
    n_nuisance, nuisance_lo, nuisance_hi : int, float, float
        Per-track parameters and their bounds.
    mode, input_effect, exo_columns, signature, neutral, needs_columns : object
        The other fields of :class:`~bayesid.models.effects.Effect`.
    coefficient : str
        The shifted coefficient (a name of :data:`~bayesid.models.ship.layout.COEFFICIENTS`).
    """

    coefficient: str = ""

    @property
    def sets(self) -> tuple:
        """The ship file's coefficient the effect sets (a model cannot also fit it)."""
        return (self.coefficient,)

    def kernel(self, kp, q):
        kp["prm"][:, COEFFICIENT_INDEX[self.coefficient]] += q[:, 0]

    def vehicle_coefficients(self, q, vehicle) -> dict:
        """The ship file's coefficient once shifted by fitted ``q``.

        Parameters
        ----------
        q : array_like, shape (1,)
            The shift.
        vehicle : Ship
            The ship: its value of the coefficient.

        Returns
        -------
        dict
            ``{coefficient: file value + shift}``.
        """
        return {self.coefficient: float(vehicle.coefficients[self.coefficient] + q[0])}

    def force_signature(self, m):
        if self.coefficient != "Xuu":  # the others act through the propeller and rudder models
            return None
        pr, u = m["particulars"], m["u"]
        z = np.zeros(u.size)
        return [np.column_stack([0.5 * pr["rho"] * pr["L"] * pr["d"] * u * np.abs(u), z, z])]


_MMG = "Yasukawa & Yoshimura (2015), J. Mar. Sci. Technol. 20:37-52"

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
    "wake_in_turn": ShipWakeInTurn(
        "wake_in_turn",
        WAKE_IN_TURN,
        (0.05, 0.3, 0.3),
        (10.0, 3.0, 3.0),
        (2.0, 1.6, 1.1),
        (0.5, 0.2, 0.2),
        neutral=None,
        description="the MMG 2015 wake in a turn, 1 - w_P = (1 - wP)(1 + (1 - exp(-C1|beta_P|))(C2 - 1)), "
        "C2 for beta_P > 0 and C2m for beta_P < 0, in place of wP exp(-4 beta_P^2)",
        source=f"{_MMG}, eq. 16; start values their KVLCC2 L7 (C1 2.0, C2 1.6 and 1.1)",
    ),
    "coupling_speed": ShipCouplingSpeed(
        "coupling_speed",
        ("c_U",),
        (0.0,),
        (1.0,),
        (1.0,),
        (0.3,),
        neutral=(0.0,),
        description="MMG 2015's coupling speed: the hull's coupling terms Yvvr, Yvrr, Nvvr, Nvrr divided by "
        "sqrt(u^2 + v^2 + (1 - c_U)(rL)^2), c_U = 1 being MMG's U = sqrt(u^2 + v^2) in place of the package's "
        "sqrt(u^2 + v^2 + (rL)^2)",
        source=f"{_MMG}, eqs. 6-8; the package's form stays finite at zero speed and gives these terms "
        "0.6-0.75 of MMG's in a hard turn (benchmarks/shipmmg_turn.py)",
    ),
    "rudder_resistance": ShipCoefficientShift(
        "rudder_resistance",
        ("dtR",),
        (-0.6,),
        (0.6,),
        (0.0,),
        (0.1,),
        neutral=(0.0,),
        coefficient="tR",
        description="the rudder's resistance in a turn: a shift of the steering resistance deduction t_R "
        "in X_R = -(1 - t_R) F_N sin(delta)",
        source=f"{_MMG}, eq. 12; t_R from captive tests (KVLCC2 0.387), often estimated from other hulls",
    ),
    "thrust_deduction": ShipCoefficientShift(
        "thrust_deduction",
        ("dtP",),
        (-0.3,),
        (0.3,),
        (0.0,),
        (0.05,),
        neutral=(0.0,),
        coefficient="tP",
        description="the propeller's thrust deduction: a shift of t_P in X_P = (1 - t_P) T",
        source=f"{_MMG}, eq. 9; t_P from a self-propulsion test, which a free-running model in another "
        "basin or at another rpm need not share",
    ),
    "propulsion_point": ShipCoefficientShift(
        "propulsion_point",
        ("dwP",),
        (-0.3,),
        (0.3,),
        (0.0,),
        (0.05,),
        neutral=(0.0,),
        coefficient="wP",
        description="the propulsion point: a shift of the effective wake fraction w_P0 (thrust identity), "
        "i.e. the rpm a speed needs",
        source=f"{_MMG}, eqs. 10-11; the rpm against speed differs between basins and between model and ship",
    ),
    "hull_resistance": ShipCoefficientShift(
        "hull_resistance",
        ("dXuu",),
        (-0.03,),
        (0.03,),
        (0.0,),
        (0.005,),
        neutral=(0.0,),
        coefficient="Xuu",
        description="the hull's resistance: a shift of X'uu = -R'0",
        source=f"{_MMG}, eq. 8; R'0 from a resistance test, scaled or from another basin",
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


__all__ = [
    "SHIP_CATALOGUE",
    "get_effect",
    "ShipWind",
    "ShipCurrent",
    "ShipDelay",
    "ShipWakeInTurn",
    "ShipCoefficientShift",
]
