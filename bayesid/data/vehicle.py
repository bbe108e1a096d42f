"""Vehicle description (mass properties, geometry, hydrostatics, propulsion, limits, coefficients)
and its TOML loader.

Vehicle files (the packaged ones: :func:`packaged_vehicles`) have the sections ``[vehicle]``,
``[inertia]``, ``[geometry]``, ``[coefficients]`` (prime form), ``[propulsion]``, ``[crossflow]``,
``[limits]``, ``[source]`` and ``[prior]`` (:mod:`bayesid.data.priors`).
"""

from __future__ import annotations

import copy
import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from . import terms
from .priors import parse_prior_section


class VehicleFileError(ValueError):
    """A vehicle file is missing a key, has an unknown key or a non-finite value."""


@dataclass(frozen=True)
class Propulsion:
    """Healey & Lienard (1993) propulsion model (equations.md, "Propulsion as implemented").

    ``u_c = uc_per_omega * n`` (n in rad/s), ``eta = u_c/u``; the axial force is the ``Cd0`` term of
    the term library; ``eps(eta)`` multiplies the ``_eps`` terms, with
    ``C_T = CT_coeff*L**2*eta|eta|/2`` and ``C_T1 = CT_coeff*L**2/2``.

    Parameters
    ----------
    uc_per_omega : float
        Ratio of the propeller-induced speed ``u_c`` to the shaft speed, m (per rad/s).
    CT_coeff : float
        Thrust coefficient of ``C_T`` above.
    """

    uc_per_omega: float  # m (per rad/s)
    CT_coeff: float


@dataclass(frozen=True)
class Crossflow:
    """Strip-sum cross-flow drag (Feldman 1979 as implemented in MSS ``npsauv.m``).

    The force is ``-(rho/2) * sum_i w_i * g(x_i) * (v + x_i r)/U_cf(x_i)`` (equations.md,
    "Crossflow drag as implemented"); ``stations`` and ``weights`` are the strip positions (m) and
    lengths (m). We follow the vehicle file's MSS strip sum: every station carries the full ``dx``.

    Parameters
    ----------
    Cdy : float
        Cross-flow drag coefficient in sway.
    Cdz : float
        Cross-flow drag coefficient in heave.
    height_m : float
        Hull height, m (``Cdy * height_m`` weighs the sway cross flow of a strip).
    breadth_m : float
        Hull breadth, m (``Cdz * breadth_m`` weighs the heave cross flow of a strip).
    stations : ndarray, shape (n_strips,)
        Strip positions along the body x axis, m.
    weights : ndarray, shape (n_strips,)
        Strip lengths, m.
    """

    Cdy: float
    Cdz: float
    height_m: float
    breadth_m: float
    stations: np.ndarray  # (n_strips,) m
    weights: np.ndarray  # (n_strips,) m


@dataclass(frozen=True)
class Limits:
    """Control limits, radians and rpm.

    Parameters
    ----------
    rudder_max : float
        Largest rudder angle, rad.
    stern_plane_max : float
        Largest stern-plane angle, rad.
    bow_plane_max : float
        Largest bow-plane angle, rad.
    rpm_max : float
        Largest propeller speed, rpm.
    actuator_time_constant_s : float, optional
        Time constant of the control-surface actuators, s (None: not given).
    """

    rudder_max: float
    stern_plane_max: float
    bow_plane_max: float
    rpm_max: float
    actuator_time_constant_s: float | None = None

    def check(self, inputs: np.ndarray, where: str = "inputs") -> None:
        """Raise ValueError naming the channel and sample if ``inputs`` exceed the limits
        (1e-12 rad tolerance) or are not finite.

        Parameters
        ----------
        inputs : ndarray, shape (n, 4)
            ``delta_r, delta_s, delta_b`` (rad) and ``n`` (rpm) per sample.
        where : str, default "inputs"
            What the inputs are, at the start of the message.

        Raises
        ------
        ValueError
            At the first non-finite value or value beyond its limit, naming channel and sample.
        """
        lim = (self.rudder_max, self.stern_plane_max, self.bow_plane_max, self.rpm_max)
        for j, name in enumerate(("delta_r", "delta_s", "delta_b", "n")):
            col = inputs[:, j]
            bad = np.flatnonzero(~np.isfinite(col))
            if bad.size:
                raise ValueError(f"{where}: non-finite {name} at sample {bad[0]}")
            over = np.flatnonzero(np.abs(col) > lim[j] + 1e-12)
            if over.size:
                raise ValueError(
                    f"{where}: {name} = {col[over[0]]:.6g} at sample {over[0]} exceeds the limit {lim[j]:.6g}"
                )


@dataclass(frozen=True)
class Vehicle:
    """A vehicle: everything the simulator needs. Coefficients are in prime form.

    Use :func:`load_vehicle` to build one from a file; ``with_coefficients`` and
    ``with_crossflow`` return modified copies (the object itself is immutable).

    Parameters
    ----------
    id : str
        Vehicle id (the packaged file's stem, e.g. ``"nps_auv2"``).
    name : str
        Display name.
    L : float
        Reference length, m.
    rho : float
        Water density, kg/m^3.
    g : float
        Gravitational acceleration, m/s^2.
    mass : float
        Mass, kg.
    weight : float
        Weight, N.
    buoyancy : float
        Buoyancy, N.
    inertia : ndarray, shape (3, 3)
        Inertia tensor about the body origin, kg m^2, ``[[Ix, -Ixy, -Ixz], ...]``.
    rG : ndarray, shape (3,)
        Centre of gravity in body axes, m.
    rB : ndarray, shape (3,)
        Centre of buoyancy in body axes, m.
    coefficients : dict
        ``{name: prime value}`` of the terms (every table term; absent ones are 0).
    propulsion : Propulsion
        The propulsion model.
    limits : Limits
        The control limits.
    crossflow : Crossflow, optional
        The strip-sum cross-flow drag (None: the file has no ``[crossflow]`` section).
    crossflow_model : str, default "polynomial"
        ``"polynomial"`` (the Gertler & Hagen terms) or ``"integral"`` (the strip sum).
    nominal_speed : float, default 1.0
        Steady straight speed at the nominal rpm, m/s.
    nominal_rpm : float, default 0.0
        Nominal propeller speed, rpm.
    source : dict
        The file's ``[source]`` section.
    path : str, default ""
        The file the vehicle was loaded from ("" when built in code).
    prior : dict
        ``{name: (mean, sd)}`` Gaussian priors of the file's ``[prior]`` section (prime form).
    prior_source : str, default ""
        The ``[prior]`` section's source text.
    """

    id: str
    name: str
    L: float  # m
    rho: float  # kg/m^3
    g: float  # m/s^2
    mass: float  # kg
    weight: float  # N
    buoyancy: float  # N
    inertia: np.ndarray  # (3, 3) kg m^2 about the body origin, [[Ix,-Ixy,-Ixz],...]
    rG: np.ndarray  # (3,) m
    rB: np.ndarray  # (3,) m
    coefficients: dict  # name -> prime value (every table term; absent ones are 0)
    propulsion: Propulsion
    limits: Limits
    crossflow: Crossflow | None = None
    crossflow_model: str = "polynomial"  # "polynomial" (GH terms) or "integral" (strip sum)
    nominal_speed: float = 1.0  # m/s, steady straight speed at nominal rpm
    nominal_rpm: float = 0.0
    source: dict = field(default_factory=dict)
    path: str = ""
    #: {name: (mean, sd)} Gaussian priors of the file's ``[prior]`` section, and their source
    prior: dict = field(default_factory=dict)
    prior_source: str = ""

    def __setstate__(self, state):
        # A process that unpickles a vehicle (a joblib or Dask worker) starts from the listed term
        # table: add this vehicle's products to it before anything reads terms.NAMES.
        terms.check_names(state.get("coefficients", {}), f"vehicle {state.get('id', '')}")
        self.__dict__.update(state)

    @property
    def file_path(self) -> str:
        """The TOML file the vehicle was loaded from ("" when built in code)."""
        return self.path

    @property
    def display_name(self) -> str:
        """The vehicle's name (for the vessel check of a track)."""
        return self.name

    def track_warnings(self, track, name: str, body_speed, ground_speed) -> list[str]:
        """Plausibility warnings of a track for this vehicle (:func:`bayesid.data.validate.check_track`):
        a median speed over ground above 4 x the nominal speed.

        Parameters
        ----------
        track : Track
            The track (not read here; vessel families that check its columns do).
        name : str
            The file named in messages.
        body_speed : float or None
            Median speed through the water from ``u, v``, m/s (unused here).
        ground_speed : float or None
            Median speed over ground from the positions, m/s (None: no positions).

        Returns
        -------
        list of str
            The warnings (empty when nothing looks odd).
        """
        if self.nominal_rpm > 0 and ground_speed is not None and ground_speed > 4.0 * self.nominal_speed:
            return [
                f"{name}: median speed over ground {ground_speed:.3g} m/s is more than 4 x the vehicle's "
                f"nominal {self.nominal_speed:.3g} m/s: a track of another vessel, or positions not in metres?"
            ]
        return []

    def coefficient_vector(self, names=None) -> np.ndarray:
        """Prime coefficients as an array, in ``names`` order.

        Parameters
        ----------
        names : sequence of str, optional
            The P coefficient names; default the whole table (:data:`bayesid.data.terms.NAMES`).

        Returns
        -------
        ndarray, shape (P,)
            The prime values (0 for a term the vehicle does not list).

        Raises
        ------
        UnknownCoefficientError
            For a name that is not a term.
        """
        names = terms.NAMES if names is None else names
        terms.check_names(names, f"vehicle {self.id}")
        return np.array([self.coefficients.get(n, 0.0) for n in names], dtype=float)

    def with_coefficients(self, values: dict) -> Vehicle:
        """Copy with some coefficients replaced.

        Parameters
        ----------
        values : dict
            ``{name: prime value}`` of the coefficients to replace or add.

        Returns
        -------
        Vehicle
            The modified copy.

        Raises
        ------
        UnknownCoefficientError
            For a name that is not a term.
        ValueError
            For a non-finite value, naming the coefficient.
        """
        terms.check_names(values, f"vehicle {self.id}")
        new = dict(self.coefficients)
        for k, v in values.items():
            if not math.isfinite(float(v)):
                raise ValueError(f"coefficient {k} = {v} is not finite")
            new[k] = float(v)
        return replace(self, coefficients=new)

    def with_crossflow(self, model: str) -> Vehicle:
        """Select the nonlinear sway/yaw (and heave/pitch) damping.

        ``"polynomial"``: the Gertler & Hagen terms (``Yvabsv`` ...) of the coefficient table.
        ``"integral"``: the strip-sum cross-flow integral; the polynomial terms are set to zero so
        the damping is not counted twice.

        Parameters
        ----------
        model : {"polynomial", "integral"}
            The damping model.

        Returns
        -------
        Vehicle
            ``self`` for ``"polynomial"``, else a copy with the polynomial terms zeroed.

        Raises
        ------
        ValueError
            For another model name, ``"integral"`` without a ``[crossflow]`` section, or
            ``"polynomial"`` on a copy whose polynomial terms were removed.
        """
        if model == "polynomial":
            if self.crossflow_model == "integral":
                raise ValueError("this vehicle copy had its polynomial terms removed; reload it")
            return self
        if model != "integral":
            raise ValueError(f"crossflow model must be 'polynomial' or 'integral', not {model!r}")
        if self.crossflow is None:
            raise ValueError(f"vehicle {self.id} has no [crossflow] section")
        zeroed = {n: 0.0 for n in terms.CROSSFLOW_POLYNOMIAL}
        return replace(self.with_coefficients(zeroed), crossflow_model="integral")

    def without_products_of_inertia(self) -> Vehicle:
        """Copy with Ixy = Iyz = Ixz = 0 (port/starboard symmetric mass distribution).

        Returns
        -------
        Vehicle
            The modified copy.
        """
        return replace(self, inertia=np.diag(np.diag(self.inertia)))

    @property
    def m_prime(self) -> float:
        """Non-dimensional mass m' = m / (0.5 rho L^3)."""
        return self.mass / (0.5 * self.rho * self.L**3)

    def mass_matrix(self, coefficients: dict | None = None) -> np.ndarray:
        """Rigid-body plus added mass, ``M = M_RB - M_A`` (6, 6), SI.

        Rows X, Y, Z, K, M, N; columns u', v', w', p', q', r' (accelerations). Rigid-body part from
        the left-hand sides of equations.md "Rigid body" (Feldman 1979; paper Eq. 1); the added
        mass of term ``Yrdot`` enters at (Y, r) as ``-0.5*rho*L**4*Yrdot``.

        Parameters
        ----------
        coefficients : dict, optional
            ``{name: prime value}`` to take the added-mass terms from; default the vehicle's.

        Returns
        -------
        ndarray, shape (6, 6)
            The mass matrix, SI.
        """
        c = self.coefficients if coefficients is None else coefficients
        m = self.mass
        xg, yg, zg = self.rG
        M = np.zeros((6, 6))
        M[:3, :3] = m * np.eye(3)
        S = np.array([[0.0, -zg, yg], [zg, 0.0, -xg], [-yg, xg, 0.0]])  # S(rG): S(a) b = a x b
        M[:3, 3:] = -m * S
        M[3:, :3] = m * S
        M[3:, 3:] = self.inertia
        for name in terms.names_where(kind="added_mass"):
            val = c.get(name, 0.0)
            if val:
                t = terms.term(name)
                M[t.dof, t.accel] -= 0.5 * self.rho * self.L**t.L_power * val
        return M

    def steady_speed(self, rpm: float) -> float:
        """Straight-line steady speed for a propeller speed (eta = 1: u = u_c).

        Parameters
        ----------
        rpm : float
            Propeller speed, rpm.

        Returns
        -------
        float
            The steady speed, m/s.
        """
        return self.propulsion.uc_per_omega * rpm * 2.0 * math.pi / 60.0


_REQUIRED = {
    "vehicle": ("id", "length_m", "weight_N", "buoyancy_N", "mass_kg", "rho"),
    "inertia": ("Ixx", "Iyy", "Izz"),
    "geometry": ("rG", "rB"),
    "propulsion": ("uc_per_omega", "CT_coeff"),
    "limits": ("rudder_max_deg", "stern_plane_max_deg", "bow_plane_max_deg", "rpm_max"),
}


def _finite(path, section, key, value):
    vals = value if isinstance(value, list) else [value]
    for v in vals:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise VehicleFileError(f"{path}: [{section}] {key} = {value!r} is not a finite number")
    return value


class _KnownTerms:
    """Membership test of the term library for a ``[prior]`` section (any product it can build)."""

    def __contains__(self, name) -> bool:
        try:
            terms.term(name)
        except (terms.UnknownCoefficientError, KeyError, ValueError):
            return False
        return True


#: Vehicle files the docs work with that are not packaged (id -> path in the source tree): a user who
#: read the docs and gives the id is told where the file is
DOCS_EXAMPLES = {"kvlcc2_7m_mmg": "docs/vessels/kvlcc2_7m_mmg.toml"}


def docs_example_hint(path_or_id) -> str:
    """The end of the error for an id that is not packaged: where the docs' file of that id is
    (:data:`DOCS_EXAMPLES`), or nothing.

    Parameters
    ----------
    path_or_id : str or Path
        The id the user gave.

    Returns
    -------
    str
        ``"; kvlcc2_7m_mmg is a worked example of the docs, ..."`` or ``""``.
    """
    path = DOCS_EXAMPLES.get(str(path_or_id).lower())
    if path is None:
        return ""
    return f"; {path_or_id} is a worked example of the docs, not packaged: its file is {path} in the source tree (give that path)"


def packaged_vehicles() -> list[str]:
    """Ids of the vehicle files shipped with the package.

    Returns
    -------
    list of str
        The ids (file stems), sorted.
    """
    root = resources.files("bayesid") / "vehicles"
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def load_vehicle(path_or_id: str | Path) -> Vehicle:
    """Load a vehicle file.

    Parameters
    ----------
    path_or_id : str or Path
        A path to a TOML file, or the id of a packaged vehicle (``"nps_auv2"``).

    Returns
    -------
    Vehicle
        The vehicle, with the file's cross-flow model selected (:meth:`Vehicle.with_crossflow`).

    Raises
    ------
    FileNotFoundError
        No such file or packaged id.
    VehicleFileError
        Missing mass property or section, non-finite value, unsupported form, a ship file;
        the message names the file, section and key.
    UnknownCoefficientError
        A coefficient name not in the term library (names file and key).
    """
    if not str(path_or_id).strip():
        raise FileNotFoundError(f"empty vehicle name; give a packaged id ({packaged_vehicles()}) or a TOML path")
    p = Path(path_or_id)
    if not p.suffix and not p.exists():
        res = resources.files("bayesid") / "vehicles" / f"{path_or_id}.toml"
        if not res.is_file():
            raise FileNotFoundError(
                f"no vehicle file {path_or_id!r}; packaged: {packaged_vehicles()}{docs_example_hint(path_or_id)}"
            )
        p = Path(str(res))
    if not p.is_file():
        raise FileNotFoundError(f"vehicle file {p} does not exist")
    try:
        with open(p, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as e:
        raise VehicleFileError(f"{p}: not valid TOML: {e}") from None

    if doc.get("vehicle", {}).get("kind") == "ship3dof":
        raise VehicleFileError(
            f'{p}: a ship file ([vehicle] kind = "ship3dof"); load it with '
            "bayesid.models.ship.load_ship, or bayesid.models.load_any_vehicle for either kind"
        )
    for section, keys in _REQUIRED.items():
        if section not in doc:
            raise VehicleFileError(f"{p}: missing section [{section}]")
        for k in keys:
            if k not in doc[section]:
                raise VehicleFileError(f"{p}: missing [{section}] {k}")
            if k != "id":
                _finite(p, section, k, doc[section][k])
    v = doc["vehicle"]
    for k in ("length_m", "mass_kg", "weight_N", "buoyancy_N", "rho"):
        if k in v and not float(v[k]) > 0:
            raise VehicleFileError(f"{p}: [vehicle] {k} = {v[k]!r} must be positive")
    form = v.get("coefficient_form", "prime")
    if form != "prime":
        raise VehicleFileError(
            f"{p}: [vehicle] coefficient_form = {form!r}; only 'prime' coefficients "
            "are supported (convert to prime form, see equations.md)"
        )
    if "coefficients" not in doc:
        raise VehicleFileError(f"{p}: missing section [coefficients]")
    coeffs = {}
    for k, val in doc["coefficients"].items():
        if k not in terms.INDEX:
            try:
                terms.term(k)
            except terms.UnknownCoefficientError as e:
                raise terms.UnknownCoefficientError(f"{p}: [coefficients] {e}") from None
        coeffs[k] = float(_finite(p, "coefficients", k, val))
    prop = doc["propulsion"]
    if "Cd0" in prop:  # the vehicle files keep Cd0 with the propulsion model; it is a term here
        if "Cd0" in coeffs:
            raise VehicleFileError(f"{p}: Cd0 given in both [propulsion] and [coefficients]")
        coeffs["Cd0"] = float(_finite(p, "propulsion", "Cd0", prop["Cd0"]))

    ine = doc["inertia"]
    for k in ("Ixy", "Iyz", "Ixz"):
        if k in ine:
            _finite(p, "inertia", k, ine[k])
    Ixy, Iyz, Ixz = ine.get("Ixy", 0.0), ine.get("Iyz", 0.0), ine.get("Ixz", 0.0)
    inertia = np.array([[ine["Ixx"], -Ixy, -Ixz], [-Ixy, ine["Iyy"], -Iyz], [-Ixz, -Iyz, ine["Izz"]]], dtype=float)
    geo = doc["geometry"]
    for k in ("rG", "rB"):
        if len(geo[k]) != 3:
            raise VehicleFileError(f"{p}: [geometry] {k} must have 3 components")
    lim = doc["limits"]
    limits = Limits(
        rudder_max=math.radians(lim["rudder_max_deg"]),
        stern_plane_max=math.radians(lim["stern_plane_max_deg"]),
        bow_plane_max=math.radians(lim["bow_plane_max_deg"]),
        rpm_max=float(lim["rpm_max"]),
        actuator_time_constant_s=lim.get("actuator_time_constant_s"),
    )
    crossflow = None
    model = "polynomial"
    if "crossflow" in doc:
        cf = doc["crossflow"]
        for k in ("Cdy", "Cdz", "height_m", "breadth_m", "x_start_m", "x_end_m", "n_strips", "dx_m"):
            if k not in cf:
                raise VehicleFileError(f"{p}: missing [crossflow] {k}")
            _finite(p, "crossflow", k, cf[k])
        xs = np.linspace(cf["x_start_m"], cf["x_end_m"], int(cf["n_strips"]))
        crossflow = Crossflow(
            cf["Cdy"], cf["Cdz"], cf["height_m"], cf["breadth_m"], xs, np.full(xs.shape, float(cf["dx_m"]))
        )
        model = cf.get("model", "polynomial")
    prior, prior_source = parse_prior_section(doc.get("prior", {}), p, coeffs, _KnownTerms(), VehicleFileError)
    L = float(v["length_m"])
    propulsion = Propulsion(float(prop["uc_per_omega"]), float(prop["CT_coeff"]))
    rpm = float(v.get("max_rpm", lim["rpm_max"]))
    veh = Vehicle(
        id=str(v["id"]),
        name=str(v.get("name", v["id"])),
        L=L,
        rho=float(v["rho"]),
        g=float(v.get("g", 9.81)),
        mass=float(v["mass_kg"]),
        weight=float(v["weight_N"]),
        buoyancy=float(v["buoyancy_N"]),
        inertia=inertia,
        rG=np.array(geo["rG"], dtype=float),
        rB=np.array(geo["rB"], dtype=float),
        coefficients=coeffs,
        propulsion=propulsion,
        limits=limits,
        crossflow=crossflow,
        crossflow_model="polynomial",
        nominal_speed=float(v.get("nominal_speed_mps", propulsion.uc_per_omega * rpm * math.pi / 30)),
        nominal_rpm=rpm,
        source=copy.deepcopy(doc.get("source", {})),
        path=str(p),
        prior=prior,
        prior_source=prior_source,
    )
    if model == "integral":
        veh = veh.with_crossflow("integral")
    elif model != "polynomial":
        raise VehicleFileError(f"{p}: [crossflow] model must be 'polynomial' or 'integral'")
    return veh
