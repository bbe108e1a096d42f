"""A 3-DOF surface-ship model (surge, sway, yaw) in the MMG form, for free-running model tests.

Equations (Yasukawa & Yoshimura 2015, "Introduction of MMG standard method for ship maneuvering
predictions", J. Mar. Sci. Technol. 20:37-52, Sec. 2, eqs. 4-5, with the motion at midship)::

    (m + mx) u' - (m + my) v r - xG m r^2  = XH + XP + XR + XW
    (m + my) v' + xG m r' + (m + mx) u r   = YH + YR + YW
    (IzG + xG^2 m + Jz) r' + xG m (v' + u r) = NH + NR + NW

Hull forces (``q = 0.5 rho L d``; prime coefficients in the MMG system)::

    XH = q (Xuu u|u| + Xvv v^2 + Xvr v r L + Xrr r^2 L^2)
    YH = q (Yv U v + Yr u r L)          - 0.5 rho d Ycf  int (v + x r)|v + x r| dx
    NH = q L (Nv u v + Nr U r L)        - 0.5 rho d Ncf  int x (v + x r)|v + x r| dx

plus the MMG coupling terms ``Yvvr v'^2 r' U^2``, ``Yvrr v' r'^2 U^2`` (and ``Nvvr``, ``Nvrr``)
written ``q Yvvr v^2 (rL) / Ut`` with ``Ut = sqrt(u^2 + v^2 + (rL)^2)`` (``Ut = U sqrt(1 + r'^2)``:
close to MMG's ``U`` in gentle manoeuvres, and bounded by ``Ut^2`` at every speed; but in a hard turn
it is not: at the ``r'`` of 0.9-1.3 of a 35 deg turn the coupling terms are 0.6-0.75 of MMG's, which
tightens the steady turn, ``benchmarks/shipmmg_turn.py``; a ship file's ``[form] coupling_speed =
"U"`` divides them by MMG's ``U`` instead, :data:`~bayesid.models.ship.layout.FORMS`),
with ``U = sqrt(u^2 + v^2)`` and the integrals over ``x`` in ``[-L/2, L/2]`` (16-point
Gauss-Legendre). For a ship going ahead (``u = U``) the linear terms are the MMG ones
(``Y'v v' U^2 = Yv U v``). The cubic MMG terms (``v'^3 U^2 = v^3 / U``) are singular in ``r``
at ``U -> 0``; they are replaced by the cross-flow drag integral (Oltmann & Sharma 1984;
Yoshimura's low-speed MMG), which is finite at every speed, including pure sway, rotation on
the spot and going astern (the berthing runs). The two forms are not alike in a hard turn: the
packaged KVLCC2 file's ``Ycf`` 0.45, ``Ncf`` 0.25 in place of MMG 2015's cubic terms is the largest
single reason its 35 deg turn's steady diameter is 0.51 of the tactical one where the MMG model with
the published coefficients gives 0.72-0.74 (``benchmarks/shipmmg_turn.py``). The factors ``U`` / ``u`` follow the fore-aft
mirror symmetry (``u -> -u``, ``r -> -r``): sway force even in ``u``, yaw moment odd.
``Xuu = -R'0``, so the resistance opposes the motion astern too.

Propeller (Yasukawa & Yoshimura 2015, eqs. 9-12)::

    XP = (1 - tP) T,   T = rho n^2 D^4 KT(J),  J = u (1 - w) / (n D),
    KT = k0 + k1 J + k2 J^2 (J clipped to [-0.5, 1.2]),   w = wP exp(-4 beta_P^2),
    beta_P = -(v + xP L r) / |U_P| ;   n < 0 (astern): T = -Ka rho n^2 D^4.

or, where the ship file (or the ``wake_in_turn`` effect) gives ``C1 > 0``, the MMG 2015 wake in a
turn (Yasukawa & Yoshimura 2015, eq. 16; KVLCC2: C1 = 2.0, C2 = 1.6, C2m = 1.1)::

    1 - w = (1 - wP) (1 + (1 - exp(-C1 |beta_P|)) (C2 - 1)),   C2m in place of C2 for beta_P < 0,
    beta_P = atan(-(v + xP L r) / |u|)   (MMG's beta - x'_P r' to first order).

Rudder (MMG, eqs. 13-23; delta_MMG = dR0 - delta_r: the package's rudder is positive to port)::

    FN = 0.5 rho AR f_alpha UR (uR sin(delta) - vR cos(delta))     (= 0.5 rho AR f UR^2 sin(alpha_R))
    uR = eps sqrt(eta (uP (1 - kappa) + kappa sqrt(uP^2 + 8 KT n^2 D^2 / pi))^2 + (1 - eta) uP^2)
    vR = -gamma_R (v + lR L r),   XR = -(1 - tR) FN sin(delta),
    YR = -(1 + aH) FN cos(delta),   NR = -(xR + aH xH) L FN cos(delta),

with ``f_alpha = 6.13 lambda / (lambda + 2.25)`` (Fujii's formula, MMG eq. 22) and the
flow-straightening coefficient ``gamma_R = gR`` for ``beta_R >= 0`` (``v + lR L r <= 0``: the stern
moving to port, as in a turn to starboard), ``gRm`` for ``beta_R < 0`` (MMG ``v_R = U gamma_R
beta_R``, ``beta_R = beta - l'_R r'``, a value for each sign; ``gRm`` is ``gR`` unless the ship
file gives it, :data:`~bayesid.models.ship.layout.FOLLOWS`). The inflow is
written in velocities (not ``J``), so it stays finite at ``u -> 0``; going astern (``uP < 0``)
the rudder sees the reverse free stream and, with the propeller ahead, its slipstream.
``dR0`` (rad, package convention; 0 unless a file or a fit sets it) is the neutral rudder angle:
the rudder angle at which the rudder gives no normal force going straight ahead. It absorbs the
port/starboard asymmetry of a single propeller's slipstream (its swirl at the rudder) and a
rudder zero offset with one parameter -- our simplification; the MMG standard's own
port/starboard asymmetry is the two-sided ``gamma_R`` (``gR``, ``gRm``), which acts in the turn
(through ``beta_R``) rather than at zero rudder.

Wind (Fujiwara, Ueno & Nimura 1998 -- the Fourier form, truncated to seven coefficients)::

    XW = 0.5 rho_a VA^2 AT (Cx1 cos g + Cx3 cos 3g)
    YW = 0.5 rho_a VA^2 AL (Cy1 sin g + Cy3 sin 3g)
    NW = 0.5 rho_a VA^2 AL L (Cn1 sin g + Cn2 sin 2g + Cn3 sin 3g)

``VA``, ``g``: apparent wind speed and the angle it comes from, off the bow (positive from
starboard), from the measured true wind (track columns ``wind_speed``, ``wind_dir``) and the
ship's velocity over ground. The yaw moment keeps Fujiwara's three sine harmonics: with two, its
peak off the quarter (wind from 110-140 deg, where a tanker's aft superstructure dominates) is
tied to the bow-quarter peak; on the Esso validation split the third harmonic takes the held-out
60 s error from 0.754 m to 0.740 m (studies/real_ships.py, with the wind, 40 evaluations).

Added mass (:func:`~bayesid.models.ship.fileformat.empirical_added_mass`): ``my``, ``Jz`` from
Clarke, Gedling & Hine (1983), "The application of manoeuvring criteria in hull design using
linear theory", Trans. RINA 125; ``mx = 2.7 rho V^(5/3) / L^2`` (Soeding 1982, Schiffstechnik
29). Both are converted to the MMG prime system (``0.5 rho L^2 d``, ``0.5 rho L^4 d``).

State (6,): ``x, y`` (m, earth-fixed, midship), ``psi`` (rad), ``u, v`` (m/s, through the water
at midship), ``r`` (rad/s). Inputs: rudder ``delta_r`` (rad, + to port) and propeller ``n``
(the track's rpm, used in rps).

Modules: :mod:`~bayesid.models.ship.fileformat` (the ship file,
:class:`~bayesid.models.ship.fileformat.Ship`), :mod:`~bayesid.models.ship.layout` (the kernels'
parameter vector), :mod:`~bayesid.models.ship.dynamics` (the equations as interpreted compiled
kernels; the wind of a track), :mod:`~bayesid.models.ship.kernel` (the generated kernel),
:mod:`~bayesid.models.ship.effects` (:data:`~bayesid.models.ship.effects.SHIP_CATALOGUE`),
:mod:`~bayesid.models.ship.model` (:class:`~bayesid.models.ship.model.ShipModel`),
:mod:`~bayesid.models.ship.seed` (:func:`~bayesid.models.ship.seed.equation_error_seed`) and
:mod:`~bayesid.models.ship.trials` (standard manoeuvres: turn, zigzag, pull-out, spiral). The
names a user needs are imported here: ``from bayesid.models.ship import ShipModel, load_ship``.
"""

from .effects import SHIP_CATALOGUE
from .fileformat import Ship, ShipFileError, is_ship_file, load_ship
from .layout import COEFFICIENTS, PARTICULARS, WIND
from .model import FIT_WINDOW_S, ShipModel
from .seed import equation_error_seed

__all__ = [
    "Ship",
    "ShipFileError",
    "ShipModel",
    "load_ship",
    "is_ship_file",
    "SHIP_CATALOGUE",
    "FIT_WINDOW_S",
    "equation_error_seed",
    "PARTICULARS",
    "COEFFICIENTS",
    "WIND",
]
