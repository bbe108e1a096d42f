"""The ship file: a TOML vehicle file with ``[vehicle] kind = "ship3dof"``, ``[particulars]``,
``[coefficients]``, optional ``[wind]``, ``[limits]``, ``[fit] free`` and ``[prior]`` sections, read
into a :class:`Ship` by :func:`load_ship`; :func:`is_ship_file` tells a ship file from a submarine's.
Added masses the file does not give are estimated from the particulars
(:func:`empirical_added_mass`).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from ...data.priors import parse_prior_section
from ...data.vehicle import VehicleFileError, docs_example_hint
from . import hullterms
from .layout import COEFFICIENTS, FOLLOWS, FORMS, PARTICULARS, WIND, form_slots


class ShipFileError(VehicleFileError):
    """A ship vehicle file is malformed (the message names file, section and key)."""


@dataclass
class Ship:
    """A surface ship: particulars (SI) and MMG prime coefficients.

    Parameters
    ----------
    id : str
        Ship id (the packaged file's stem, or the file's ``[vehicle] id``).
    particulars : dict
        ``{name: value}`` of every name of :data:`~bayesid.models.ship.layout.PARTICULARS` (SI,
        ratios as noted there).
    coefficients : dict
        ``{name: prime value}`` of every name of :data:`~bayesid.models.ship.layout.COEFFICIENTS`
        (added masses estimated when the file gives none; wind coefficients 0; a coefficient of
        :data:`~bayesid.models.ship.layout.FOLLOWS` the file does not give has the value of the
        one it follows), then the extra hull terms the file gives
        (:mod:`bayesid.models.ship.hullterms`).
    wind_start : dict
        Start values of the wind coefficients, from a ``[wind]`` section (the wind effect starts
        from these).
    free : list of str
        The default list of coefficients a fit changes (``[fit] free``).
    description : str, default ""
        The file's description.
    source : str, default ""
        The file the ship was loaded from ("" when built in code).
    kind : str, default "ship3dof"
        The vehicle kind.
    prior : dict
        ``{name: (mean, sd)}`` Gaussian priors of the file's ``[prior]`` section.
    prior_source : str, default ""
        The ``[prior]`` section's source text.
    scale : float, optional
        The model scale lambda, full-scale length / ``L`` (``[particulars] scale``; 1 for a
        full-scale file; None when the file does not say): Froude scaling to full scale for
        the IMO criteria (:mod:`bayesid.estimation.imo`). Not a kernel parameter.
    follows : dict
        ``{name: name}``: the coefficients of :data:`~bayesid.models.ship.layout.FOLLOWS` the file
        does not give, tied to the one they follow (``{"gRm": "gR"}``: one gamma_R for both
        sides). The kernel parameters and :meth:`with_coefficients` keep them equal; giving one a
        value (in the file, :meth:`with_coefficients` or a fit with it free) unties it. A
        coefficient of ``FOLLOWS`` missing from ``coefficients`` follows too.
    rudder_max_deg : float, optional
        The steering gear's largest rudder angle either side, deg (``[limits] rudder_max_deg``;
        None when the file gives none: no limit). ``bayesid simulate`` refuses a rudder order
        beyond it, :func:`bayesid.data.validate.check_track` warns of a track beyond it.
    form : dict
        ``{key: choice}``: the model-form choices of the file's ``[form]`` section
        (:data:`~bayesid.models.ship.layout.FORMS`; a key left out has its default, so ``{}`` is
        the package's form).
    """

    id: str
    particulars: dict
    coefficients: dict
    wind_start: dict = field(default_factory=dict)
    free: list = field(default_factory=list)
    description: str = ""
    source: str = ""
    kind: str = "ship3dof"
    #: {name: (mean, sd)} Gaussian priors of the file's ``[prior]`` section, and their source
    prior: dict = field(default_factory=dict)
    prior_source: str = ""
    scale: float | None = None
    follows: dict = field(default_factory=dict)
    rudder_max_deg: float | None = None
    form: dict = field(default_factory=dict)

    @property
    def file_path(self) -> str:
        """The TOML file the ship was loaded from ("" when built in code)."""
        return self.source

    @property
    def display_name(self) -> str:
        """No name beyond the id (for the vessel check of a track)."""
        return ""

    #: ship files give no nominal propeller speed (so no rev/s check on n)
    nominal_rpm = 0.0

    def track_warnings(self, track, name: str, body_speed, ground_speed) -> list[str]:
        """Plausibility warnings of a track for this ship (:func:`bayesid.data.validate.check_track`):
        stern/bow planes, depth or pitch that vary (a submarine's track), and a median speed
        (``body_speed`` else ``ground_speed``) above Froude number 0.25 for a full form
        (Cb >= 0.7: tankers and bulk carriers meet a wall of wave resistance near Fn 0.2) or 0.45
        for finer displacement hulls.

        Parameters
        ----------
        track : Track
            The track.
        name : str
            The file named in messages.
        body_speed : float or None
            Median speed through the water from ``u, v``, m/s.
        ground_speed : float or None
            Median speed over ground from the positions, m/s.

        Returns
        -------
        list of str
            The warnings (empty when nothing looks odd).
        """
        warn = []
        planes = [
            k
            for k in ("delta_s", "delta_b", "z", "w", "q", "theta")
            if k in track and np.nanmax(np.abs(track[k]), initial=0.0) > 1e-6
        ]
        if planes:
            warn.append(
                f"{name}: columns {', '.join(planes)} vary (stern/bow planes, depth or pitch), but "
                f"{self.id} is a 3-DOF surface ship: a submarine's track?"
            )
        L, cb = float(self.particulars.get("L", 0.0) or 0.0), float(self.particulars.get("Cb", 0.0) or 0.0)
        limit = 0.25 if cb >= 0.7 else 0.45
        speed = body_speed if body_speed is not None else ground_speed
        if L > 0 and speed is not None and speed / math.sqrt(9.81 * L) > limit:
            warn.append(
                f"{name}: median speed {speed:.3g} m/s is a Froude number of "
                f"{speed / math.sqrt(9.81 * L):.2f} for the {L:g} m {self.id} "
                f"(block coefficient {cb:g}: displacement hulls of this form run below {limit:g}): a track "
                "of another vessel, or positions not in metres?"
            )
        return warn

    @property
    def L(self) -> float:
        """Length between perpendiculars, m (``particulars["L"]``)."""
        return float(self.particulars["L"])

    @property
    def rho(self) -> float:
        """Water density, kg/m^3 (``particulars["rho"]``)."""
        return float(self.particulars["rho"])

    @property
    def tied(self) -> dict:
        """``{name: name}``: the coefficients that follow another (:attr:`follows`, and those of
        :data:`~bayesid.models.ship.layout.FOLLOWS` missing from ``coefficients``)."""
        return {k: src for k, src in FOLLOWS.items() if k in self.follows or k not in self.coefficients}

    @property
    def hull_terms(self) -> tuple:
        """The extra hull terms among the coefficients (:mod:`bayesid.models.ship.hullterms`)."""
        return hullterms.extra_terms(self.coefficients)

    def params(self, coefficients: dict | None = None) -> np.ndarray:
        """Kernel parameter vector (particulars, then the listed coefficients, then the model-form
        slots, :func:`~bayesid.models.ship.layout.form_slots`, then the extra hull terms,
        :func:`bayesid.models.ship.hullterms.encode`).

        Parameters
        ----------
        coefficients : dict, optional
            ``{name: prime value}`` replacing some of the ship's coefficients.

        Returns
        -------
        ndarray, shape (NP + TERM_WIDTH * len(hull_terms),)
            The parameter vector (:mod:`~bayesid.models.ship.layout` order).
        """
        over = coefficients or {}
        c = dict(self.coefficients, **over)
        c.update({k: c[src] for k, src in self.tied.items() if k not in over})
        head = np.array(
            [float(self.particulars[k]) for k in PARTICULARS]
            + [float(c[k]) for k in COEFFICIENTS]
            + form_slots(self.form)
        )
        return np.concatenate([head, hullterms.encode(self.hull_terms, c)])

    def with_coefficients(self, values: dict) -> Ship:
        """Copy with some coefficients replaced.

        Parameters
        ----------
        values : dict
            ``{name: prime value}``, names of :data:`~bayesid.models.ship.layout.COEFFICIENTS` or
            extra hull terms (:mod:`bayesid.models.ship.hullterms`; a new one is appended).

        Returns
        -------
        Ship
            The modified copy (its dicts and lists copied). A tied coefficient (:attr:`follows`)
            given here is untied; one not given takes the new value of the one it follows.

        Raises
        ------
        KeyError
            Naming an unknown coefficient (with the closest listed names).
        """
        for k in values:
            hullterms.check_name(k)
        follows = {k: src for k, src in self.tied.items() if k not in values}
        coef = dict(self.coefficients, **values)
        coef.update({k: coef[src] for k, src in follows.items()})
        return replace(
            self,
            particulars=dict(self.particulars),
            coefficients=coef,
            wind_start=dict(self.wind_start),
            free=list(self.free),
            prior=dict(self.prior),
            follows=follows,
            form=dict(self.form),
        )

    def with_form(self, **choices) -> Ship:
        """Copy with some model-form choices replaced (a ship file's ``[form]`` section).

        Parameters
        ----------
        **choices : str
            ``key=choice`` of :data:`~bayesid.models.ship.layout.FORMS`, e.g.
            ``coupling_speed="U"`` (MMG 2015's coupling terms).

        Returns
        -------
        Ship
            The copy.

        Raises
        ------
        ShipFileError
            An unknown key or choice (named, with the choices).
        """
        return replace(self, form=_form(self.source or self.id, {**self.form, **choices}))


def empirical_added_mass(p: dict) -> dict:
    """Added masses from the particulars, MMG prime form.

    ``my``, ``Jz``: Clarke, Gedling & Hine (1983), Trans. RINA 125, regressions
    ``-Y'vdot / (pi (T/L)^2) = 1 + 0.16 Cb B/T - 5.1 (B/L)^2`` and
    ``-N'rdot / (pi (T/L)^2) = 1/12 + 0.017 Cb B/T - 0.33 B/L`` (Clarke's primes on ``0.5 rho L^3``
    and ``0.5 rho L^5``; times ``L/d`` for the MMG primes). ``mx = 2.7 rho V^(5/3) / L^2`` with the
    displaced volume ``V = m / rho`` (Soeding 1982). For KVLCC2 this gives my' 0.244, Jz' 0.0126
    (MMG-published 0.223, 0.011; Yasukawa & Yoshimura 2015, Table 3).

    Parameters
    ----------
    p : dict
        The particulars (``L``, ``B``, ``d``, ``Cb``, ``rho``, ``mass_kg`` are read).

    Returns
    -------
    dict
        ``{"mx", "my", "Jz"}``, MMG prime form.
    """
    L, B, d, Cb, rho, m = (float(p[k]) for k in ("L", "B", "d", "Cb", "rho", "mass_kg"))
    k = math.pi * (d / L) ** 2
    yvd = k * (1.0 + 0.16 * Cb * B / d - 5.1 * (B / L) ** 2)
    nrd = k * (1.0 / 12.0 + 0.017 * Cb * B / d - 0.33 * B / L)
    V = m / rho
    mx = 2.7 * rho * V ** (5.0 / 3.0) / L**2
    return {"mx": mx / (0.5 * rho * L**2 * d), "my": yvd * L / d, "Jz": nrd * L / d}


def packaged_ships() -> list[str]:
    """Ids of the ship files shipped with the package.

    Returns
    -------
    list of str
        The ids (file stems) of the packaged files with ``kind = "ship3dof"``, sorted.
    """
    root = resources.files("bayesid") / "vehicles"
    out = []
    for p in root.iterdir():
        if p.name.endswith(".toml"):
            with open(str(p), "rb") as fh:
                if tomllib.load(fh).get("vehicle", {}).get("kind") == "ship3dof":
                    out.append(p.name[:-5])
    return sorted(out)


def is_ship_file(path_or_id) -> bool:
    """Whether a vehicle file is a ship file.

    Parameters
    ----------
    path_or_id : str or Path
        A path to a TOML file, or the id of a packaged vehicle.

    Returns
    -------
    bool
        True when the file declares ``kind = "ship3dof"`` (False for a file that cannot be read).
    """
    try:
        p = _resolve(path_or_id)
        with open(p, "rb") as fh:
            return tomllib.load(fh).get("vehicle", {}).get("kind") == "ship3dof"
    except (FileNotFoundError, tomllib.TOMLDecodeError, OSError):
        return False


def _resolve(path_or_id) -> Path:
    if not str(path_or_id).strip():
        raise FileNotFoundError("empty vehicle name; give a packaged id or a TOML path")
    p = Path(path_or_id)
    if not p.suffix and not p.exists():
        res = resources.files("bayesid") / "vehicles" / f"{path_or_id}.toml"
        if not res.is_file():
            raise FileNotFoundError(
                f"no vehicle file {path_or_id!r}; packaged ships: {packaged_ships()}{docs_example_hint(path_or_id)}"
            )
        return Path(str(res))
    if not p.is_file():
        raise FileNotFoundError(f"vehicle file {p} does not exist")
    return p


def _scale(p, v) -> float | None:
    """The ``[particulars] scale`` of file ``p`` (None when not given), checked."""
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise ShipFileError(
            f"{p}: [particulars] scale = {v!r} must be a positive finite number (the model scale: "
            "full-scale length / L; 1 for a full-scale file)"
        )
    return float(v)


#: The keys of a ship file's optional ``[limits]`` section: the steering gear's largest rudder
#: angle, deg (its rate is the approach's ``[service] rudder_rate_deg_s``).
LIMIT_KEYS = ("rudder_max_deg",)


def _rudder_max(p, sec) -> float | None:
    """The ``[limits] rudder_max_deg`` of file ``p`` (None when not given), checked."""
    if not isinstance(sec, dict):
        raise ShipFileError(f"{p}: limits = {sec!r} must be a section [limits] (rudder_max_deg = ...)")
    for k in sec:
        if k not in LIMIT_KEYS:
            hint = "; the steering gear's rate is [service] rudder_rate_deg_s" if k == "rudder_rate_deg_s" else ""
            raise ShipFileError(f"{p}: [limits] unknown key {k!r}; known: {', '.join(LIMIT_KEYS)}{hint}")
    v = sec.get("rudder_max_deg")
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v <= 90:
        raise ShipFileError(
            f"{p}: [limits] rudder_max_deg = {v!r} must be a number of degrees in (0, 90] (the steering "
            "gear's largest rudder angle either side)"
        )
    return float(v)


def _form(p, sec) -> dict:
    """The ``[form]`` section of file ``p`` (:data:`~bayesid.models.ship.layout.FORMS`), checked."""
    if not isinstance(sec, dict):
        raise ShipFileError(f'{p}: form = {sec!r} must be a section [form] (coupling_speed = "U", ...)')
    for k, v in sec.items():
        if k not in FORMS:
            raise ShipFileError(f"{p}: [form] unknown key {k!r}; known: {', '.join(FORMS)}")
        weight = k == "coupling_speed" and isinstance(v, (int, float)) and not isinstance(v, bool)
        if weight and not 0.0 <= v <= 1.0:
            raise ShipFileError(f"{p}: [form] {k} = {v!r}; a weight of (rL)^2 must lie in [0, 1] (1 is 'Ut', 0 is 'U')")
        if not weight and v not in FORMS[k]:
            raise ShipFileError(
                f"{p}: [form] {k} = {v!r}; the choices are {', '.join(repr(c) for c in FORMS[k])} "
                f"(default {FORMS[k][0]!r}) or a weight of (rL)^2 in [0, 1]"
            )
    return dict(sec)


def load_ship(path_or_id) -> Ship:
    """Load a ship vehicle file (TOML with ``[vehicle] kind = "ship3dof"``, ``[particulars]``
    (with an optional ``scale``: the model scale), ``[coefficients]``, optional ``[wind]``,
    ``[limits]`` (``rudder_max_deg``), ``[form]`` (:data:`~bayesid.models.ship.layout.FORMS`),
    ``[fit] free`` and ``[prior]``).

    Parameters
    ----------
    path_or_id : str or Path
        A path to a TOML file, or the id of a packaged ship.

    Returns
    -------
    Ship
        The ship.

    Raises
    ------
    FileNotFoundError
        No such file or packaged id.
    ShipFileError
        Missing section or particular, non-finite or non-positive value (``[particulars] scale``
        included, when given), a negative ``gR`` or ``gRm``, a ``[limits] rudder_max_deg`` outside
        (0, 90] deg, unknown key or coefficient name, a ``[form]`` key or choice the package does not
        have, a kind other than ``"ship3dof"`` (the message names the file, section and key).
    """
    p = _resolve(path_or_id)
    try:
        with open(p, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as e:
        raise ShipFileError(f"{p}: not valid TOML: {e}") from None
    for sec in ("vehicle", "particulars", "coefficients"):
        if sec not in doc:
            raise ShipFileError(f"{p}: missing section [{sec}]")

    def num(sec, k, v):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ShipFileError(f"{p}: [{sec}] {k} = {v!r} is not a finite number")
        return float(v)

    part, given = {}, dict(doc["particulars"])
    scale = _scale(p, given.pop("scale", None))
    rudder_max_deg = _rudder_max(p, doc.get("limits", {}))
    form = _form(p, doc.get("form", {}))
    for k in PARTICULARS:
        if k not in given:
            raise ShipFileError(f"{p}: missing [particulars] {k}")
        part[k] = num("particulars", k, given[k])
        if k in ("L", "B", "d", "mass_kg", "rho", "Cb", "D_prop", "A_rudder", "kzz") and not part[k] > 0:
            raise ShipFileError(f"{p}: [particulars] {k} = {part[k]!r} must be positive")
    unknown = set(given) - set(PARTICULARS)
    if unknown:
        raise ShipFileError(f"{p}: [particulars] unknown key(s) {sorted(unknown)}; known: {', '.join(PARTICULARS)}")
    coef = {k: 0.0 for k in COEFFICIENTS}
    coef.update(empirical_added_mass(part))
    for sec in ("coefficients", "wind"):
        for k, v in doc.get(sec, {}).items():
            if sec == "wind" and k not in WIND:
                raise ShipFileError(f"{p}: [wind] unknown coefficient {k!r}; known: {', '.join(WIND)}")
            if sec == "coefficients" and k in WIND:
                raise ShipFileError(f"{p}: [coefficients] {k} is a wind coefficient: give it in [wind]")
            try:
                hullterms.check_name(k)
            except hullterms.HullTermError as e:
                raise ShipFileError(f"{p}: [{sec}] {e}") from None
            coef[k] = num(sec, k, v)
    follows = {k: src for k, src in FOLLOWS.items() if k not in doc["coefficients"]}
    coef.update({k: coef[src] for k, src in follows.items()})
    for k in ("gR", "gRm"):  # gamma_R: the inflow angle at the rudder over the geometric one
        if not coef[k] >= 0.0:
            raise ShipFileError(
                f"{p}: [coefficients] {k} = {coef[k]!r} must be >= 0 (the rudder's flow-straightening "
                "coefficient gamma_R)"
            )
    if coef["C1"] < 0.0 or (coef["C1"] > 0.0 and not (coef["C2"] > 0.0 and coef["C2m"] > 0.0)):
        raise ShipFileError(
            f"{p}: [coefficients] C1 = {coef['C1']!r}, C2 = {coef['C2']!r}, C2m = {coef['C2m']!r}: the MMG 2015 "
            "wake in a turn needs C1 > 0 with C2 > 0 (and C2m > 0, or C2m left out to equal C2); C1 = 0 or "
            "left out keeps wP exp(-4 beta_P^2)"
        )
    wind = {k: coef[k] for k in WIND}
    for k in WIND:  # the base model has no wind term; the wind effect starts from these
        coef[k] = 0.0
    free = list(doc.get("fit", {}).get("free", []))
    for k in free:
        if k in WIND or k not in coef:
            hint = "" if k in WIND or not hullterms.is_term(k) else " (an extra hull term: give it in [coefficients])"
            raise ShipFileError(f"{p}: [fit] free lists unknown coefficient {k!r}{hint}")
    v = doc["vehicle"]
    if v.get("kind") != "ship3dof":
        raise ShipFileError(f'{p}: [vehicle] kind = {v.get("kind")!r}; a ship file has kind = "ship3dof"')
    prior, prior_source = parse_prior_section(
        doc.get("prior", {}), p, coef, [c for c in coef if c not in WIND], ShipFileError
    )
    return Ship(
        str(v.get("id", p.stem)),
        part,
        coef,
        wind,
        free,
        str(v.get("description", "")),
        str(p),
        prior=prior,
        prior_source=prior_source,
        scale=scale,
        follows=follows,
        rudder_max_deg=rudder_max_deg,
        form=form,
    )


__all__ = ["Ship", "ShipFileError", "load_ship", "is_ship_file", "packaged_ships", "empirical_added_mass", "LIMIT_KEYS"]
