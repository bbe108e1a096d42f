"""A generated (specialised) compiled kernel of the 3-DOF MMG ship model: the interpreted
kernel's equations, 3.5 times faster with wind (2.8 without), agreeing with it to round-off.

The interpreted kernel (:func:`bayesid.models.ship.dynamics.simulate_windows`) calls ``_rhs`` ->
``_forces`` at each RK4 stage with the state in small per-window arrays (``k1``..``k4``,
``tmp``, ``F``), reads every parameter from the parameter vector at every call, loops over the
16 Gauss-Legendre points of the cross-flow integral and evaluates eleven libm functions per
stage with wind (``sin``/``cos`` of the heading, the wake ``exp``, the rudder angle's
``sin``/``cos``, the wind's ``atan2`` and five harmonics). This module writes the Python source of a kernel in which

* the state is six scalars (``x, y, psi, u, v, r``) through the four RK4 stages: the
  right-hand side is inlined four times, no arrays in the step;
* what is constant over a window (the parameters and what is computed from them alone: the
  inverse mass matrix, ``q = 0.5 rho L d``, the leading products of the force terms) is computed
  once per window, and what is constant over a step (the rudder angle's ``sin``/``cos``,
  ``(1 - tP) rho n^2 D^4``, ``1 / (n D)``, the slipstream's ``8 n^2 D^2 / pi``) once per step;
* libm is called for ``sin``/``cos`` of the heading once per step (stages 2-4 by the addition
  theorem with the Taylor series of the small heading increment; libm again if it exceeds
  0.1 rad) and for the wake ``exp``, first in the stage (a libm call spills every live
  floating-point register, and few are live there); the wind's harmonics are algebraic in the
  apparent wind (``cos g = -ax / VA``, ``sin g = -ay / VA``, ``cos 3g = cos g (4 cos^2 g - 3)``,
  ``sin 3g = sin g (3 - 4 sin^2 g)``, ``sin 2g = 2 sin g cos g``: no ``atan2``);
* the Gauss-Legendre sum is unrolled with its nodes and weights as literals, the symmetric
  nodes ``+-x_j`` (equal weights) taken in pairs: half the additions in the two sums' chains;
* divisions by constants are multiplications by reciprocals; the rudder inflow ``UR`` comes from
  ``uR^2`` before its square root (one square root less on the propeller-rudder chain);
* the wind block is skipped per parameter row without windage (``AT > 0 or AL > 0`` false,
  ``prm[:, 14]``, ``prm[:, 15]``), a branch taken the same way through the window (a second
  kernel without the wind block is no faster on such rows and doubles the compile time);
* ``error_model="numpy"``: a zero determinant of the mass matrix gives a non-finite state and
  status 1 where the interpreted kernel raises ZeroDivisionError.

The equations are those of ``_forces`` and ``_rhs`` in :mod:`bayesid.models.ship.dynamics`
(Yasukawa & Yoshimura 2015, "Introduction of MMG standard method for ship maneuvering
predictions", J. Mar. Sci. Technol. 20:37-52, with the cross-flow, propeller, rudder and
Fujiwara wind terms as documented in :mod:`bayesid.models.ship`), term for term; the
rearrangements above change the rounding, not the model. Not bit-identical: over 3000 steps
the states differ from the interpreted kernel's by at most about 1e-15 of each channel's
largest magnitude (status and NaN layout identical).
Bit-identical is not reachable at this speed: the interpreted kernel spends 40 % of its time in
libm, and a generated kernel that keeps its calls and operation order (bit-identical) is 1.4
times faster with wind, 1.5 without.

Lanes: a thread advances :data:`LANES` parameter rows of the same window together, their
statements interleaved, so their dependency chains (the propeller-rudder chain of a division,
the ``exp``, square roots) overlap in the CPU. Measured on the development machine (AMD EPYC,
one core free; ``B = 64`` rows, one 3000-step window at dt 0.2 s, a 20-degree zigzag with wind,
best of 5 after warm-up): interpreted 380 tracks/s; generated 1 lane 1120, 2 lanes 1355,
3 lanes 1320, 4 lanes 1330 tracks/s, compiled in 4.5, 10, 15.5, 27 s. Without windage:
interpreted 570, generated (2 lanes) 1610 tracks/s.

Extra hull terms (:mod:`bayesid.models.ship.hullterms`: structure discovery's candidates, a ship
file's added terms) are not written into the source: a second kernel loops over them at run time,
reading each term's degree of freedom, exponents and coefficient from the parameter row, so that
every term set shares one compile. (A kernel specialised to each term set cost a compile of 8-17 s
per set, and a diagnosis refits a dozen or more candidate terms.) The loop multiplies each term's
factors in the order the specialised product was written in, and gives the same bits.

The generated module is written once per lane count (with and without the term loop) to
:func:`bayesid.models.codegen.cache_dir` (:func:`bayesid.models.codegen.load_module`), named by
the hash of its source, and compiled by numba with ``cache=True``, so the compile is paid once per
machine.
"""

from __future__ import annotations

import functools
import re

from ..._numba import use_package_threading_layer
from ..codegen import load_module
from . import dynamics
from .hullterms import TERM_WIDTH
from .layout import FORM_INDEX, GAUSS_W, GAUSS_X, NP

KINDS = ("generated", "interpreted")
#: parameter rows each thread advances together (interleaved; see the module docstring)
LANES = 2

# Per-window constants: statements on the lane's parameter vector ``p`` (layout.PARTICULARS, then
# layout.COEFFICIENTS; names as in dynamics._forces / dynamics._rhs) and what follows from it alone:
# om*/op* one minus/plus a coefficient, c* the constant leading factor of a force term, i* a
# reciprocal, mmx = m + mx, mmy = m + my, M11, M12, M22 the (v, r) block of the inverse mass
# matrix, cn, ce the current (m/s, north and east).
_ROW = (
    """\
L = p[0]
d = p[2]
m = p[3]
xG = p[4]
rho = p[5]
kzz = p[6]
D = p[8]
AR = p[9]
lam = p[10]
eta = p[11]
xR = p[12]
rhoa = p[13]
AT = p[14]
AL = p[15]
Xuu = p[19]
Xvv = p[20]
Xvr = p[21]
Xrr = p[22]
Yv = p[23]
Yr = p[24]
Nv = p[25]
Nr = p[26]
Ycf = p[27]
Ncf = p[28]
Yvvr = p[29]
Yvrr = p[30]
Nvvr = p[31]
Nvrr = p[32]
wP0 = p[33]
tP = p[34]
k0 = p[35]
k1 = p[36]
k2 = p[37]
Ka = p[38]
xP = p[39]
tR = p[40]
aH = p[41]
xH = p[42]
eps = p[43]
kap = p[44]
lR = p[45]
gR = p[46]
Cx1 = p[47]
Cx3 = p[48]
Cy1 = p[49]
Cy3 = p[50]
Cn1 = p[51]
Cn2 = p[52]
Cn3 = p[53]
dR0 = p[54]
gRm = p[55]
C1w = p[56]
C2w = p[57]
C2wm = p[58]
"""
    + f"kUt = p[{FORM_INDEX['coupling_rL']}]\n"
    + """\
wform = C1w > 0.0
omwP0 = 1.0 - wP0
q = 0.5 * rho * L * d
qL = q * L
h = 0.5 * L
cY = 0.5 * rho * d * Ycf * h
cN = 0.5 * rho * d * Ncf * h
xPL = xP * L
Dp4 = D ** 4
omtP = 1.0 - tP
omkap = 1.0 - kap
ometa = 1.0 - eta
eps2 = eps * eps
ck = eps * math.sqrt(eta) * kap
omseta = 1.0 - math.sqrt(eta)
mgR = -gR
mgRm = -gRm
lRL = lR * L
cFN = 0.5 * rho * AR * (6.13 * lam / (lam + 2.25))
omtR = 1.0 - tR
opaH = 1.0 + aH
cNR = (xR + aH * xH) * L
windrow = AT > 0.0 or AL > 0.0
hrhoa = 0.5 * rhoa
q2 = 0.5 * rho * L * L * d
mmx = m + p[16] * q2
mmy = m + p[17] * q2
xGm = xG * m
Iz = m * (kzz * L) ** 2 + xG * xG * m + p[18] * q2 * L * L
det = mmy * Iz - xGm * xGm
imx = 1.0 / mmx
M11 = Iz / det
M12 = -xGm / det
M22 = mmy / det
cn = cur[b, 0]
ce = cur[b, 1]"""
)

# Per-step constants of a lane (inputs held over the step; k is the step index): the rudder
# angle dm in the MMG sign convention, the propeller's sign, thrust and slipstream factors, the
# rudder force's direction factors.
_STEP = """\
dl = inputs[b, k, 0]
n = inputs[b, k, 1]
dm = dR0 - dl
sdm = math.sin(dm)
cdm = math.cos(dm)
npos = n > 1e-6
nneg = n < -1e-6
inD = 1.0 / (n * D)
cT = omtP * rho * n * n * Dp4
XPa = -omtP * Ka * rho * n * n * Dp4
c8 = 8.0 * n * n * D * D / math.pi
cXR = omtR * sdm
cYR = opaH * cdm
cNRc = cNR * cdm"""

_RHS_HEADING = """\
cps = math.cos(ps)
sps = math.sin(ps)"""

# Stages 2-4: cos and sin of the stage heading ps = ps1 + dps (dps = fac * r of the previous
# stage) from those of the step's heading ps1 by the addition theorem; the Taylor series of
# sin(dps) to dps^9 and cos(dps) to dps^10 are truncated below 3e-18 relative for |dps| < 0.1
# (libm otherwise).
_RHS_HEADING_ADD = """\
dps = fac * rprev
if abs(dps) < 0.1:
    d2 = dps * dps
    sd = dps + dps * d2 * (-1.0 / 6.0 + d2 * (1.0 / 120.0 + d2 * (-1.0 / 5040.0 + d2 * (1.0 / 362880.0))))
    cd = 1.0 + d2 * (-0.5 + d2 * (1.0 / 24.0 + d2 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0 + d2 * (-1.0 / 3628800.0)))))
    cps = cps1 * cd - sps1 * sd
    sps = sps1 * cd + cps1 * sd
else:
    cps = math.cos(ps)
    sps = math.sin(ps)"""

# The propeller's wake: omw = 1 - w_P, with w_P = wP0 exp(-4 beta_P^2), or the MMG 2015 wake in a
# turn where the row gives C1 > 0 (layout.WAKE_IN_TURN; C2m for beta_P < 0).
_RHS_HEAD = """\
vp = v + xPL * r
if wform:
    bP = math.atan2(-vp, abs(u) + 1e-12)
    omw = omwP0 * (1.0 + (1.0 - math.exp(-C1w * abs(bP))) * ((C2w if bP > 0.0 else C2wm) - 1.0))
else:
    beta2 = vp * vp / (u * u + vp * vp + 1e-12)
    omw = 1.0 - wP0 * math.exp(-4.0 * beta2)"""

# Wind (Fujiwara et al. 1998): true wind (wn, we, towards north and east) in body axes, the
# apparent wind (ax, ay) relative to the hull moving through the current, and the loads of the
# angle g it comes from (cos g, sin g = -ax / VA, -ay / VA).
_RHS_WIND = """\
XW = 0.0
YW = 0.0
NW = 0.0
if windrow:
    wbx = cps * wn + sps * we
    wby = -sps * wn + cps * we
    ax = wbx - (u + cps * cn + sps * ce)
    ay = wby - (v - sps * cn + cps * ce)
    va2 = ax * ax + ay * ay
    if va2 > 0.0:
        iva = 1.0 / math.sqrt(va2)
        cg = -ax * iva
        sg = -ay * iva
        c3g = cg * (4.0 * cg * cg - 3.0)
        s3g = sg * (3.0 - 4.0 * sg * sg)
        s2g = 2.0 * sg * cg
        qa = hrhoa * va2
        XW = qa * AT * (Cx1 * cg + Cx3 * c3g)
        YW = qa * AL * (Cy1 * sg + Cy3 * s3g)
        NW = qa * AL * L * (Cn1 * sg + Cn2 * s2g + Cn3 * s3g)"""

# Hull forces (MMG prime coefficients; the cross-flow sums i0, i1 follow).
_RHS_HULL = """\
U = math.sqrt(u * u + v * v)
X = q * (Xuu * u * abs(u) + Xvv * v * v + Xvr * v * r * L + Xrr * r * r * L * L)
Y = q * (Yv * U * v + Yr * u * r * L)
N = qL * (Nv * u * v + Nr * U * r * L)
Ut = math.sqrt(u * u + v * v + kUt * r * r * L * L)
if Ut > 1e-9:
    rl = r * L
    iUt = 1.0 / Ut
    Y += q * (Yvvr * v * v * rl + Yvrr * v * rl * rl) * iUt
    N += qL * (Nvvr * v * v * rl + Nvrr * v * rl * rl) * iUt
i0 = 0.0
i1 = 0.0"""

# Cross-flow drag, propeller thrust (KT(J), astern -Ka) and rudder normal force (MMG eqs. 9-23;
# flow straightening gR for beta_R >= 0, i.e. wR = v + lR L r <= 0, gRm otherwise).
_RHS_TAIL = """\
Y -= cY * i0
N -= cN * i1
uP = omw * u
wR = v + lRL * r
vR = (mgR if wR <= 0.0 else mgRm) * wR
if npos:
    J = min(max(uP * inD, -0.5), 1.2)
    KT = k0 + k1 * J + k2 * J * J
    X += cT * KT
    slip = math.sqrt(uP * uP + max(KT, 0.0) * c8)
    if uP >= 0.0:
        a = uP * omkap + kap * slip
        S = eta * a * a + ometa * uP * uP
        uR = eps * math.sqrt(S)
        UR = math.sqrt(eps2 * S + vR * vR)
    else:
        uR = ck * slip + omseta * uP
        UR = math.sqrt(uR * uR + vR * vR)
else:
    if nneg:
        X += XPa
    uR = eps * uP if uP >= 0.0 else uP
    UR = math.sqrt(uR * uR + vR * vR)
FN = cFN * UR * (uR * sdm - vR * cdm)
X -= FN * cXR
Y -= FN * cYR
N -= FN * cNRc"""

_RHS_WIND_ADD = """\
X += XW
Y += YW
N += NW"""

# Kinematics (earth-fixed x, y over ground with the current) and the accelerations.
_RHS_ACC = """\
D0 = u * cps - v * sps + cn
D1 = u * sps + v * cps + ce
D2 = r
D3 = (X + mmy * v * r + xGm * r * r) * imx
b1 = Y - mmx * u * r
b2 = N - xGm * u * r
D4 = M11 * b1 + M12 * b2
D5 = M12 * b1 + M22 * b2"""

_STATES = ("x", "y", "ps", "u", "v", "r")
_LHS = re.compile(r"^(\w+)\s*=", re.M)
_ROW_NAMES = set(_LHS.findall(_ROW)) | {"p", "b"}
_STEP_NAMES = set(_LHS.findall(_STEP))
# Names the inliner leaves alone: Python, the math module, the shared arrays and loop variables.
_KEEP = {
    "math",
    "abs",
    "min",
    "max",
    "if",
    "elif",
    "else",
    "and",
    "or",
    "not",
    "True",
    "False",
    "inputs",
    "cur",
    "k",
    "wn",
    "we",
    "nterm",
    "_terms",
}
_IDENT = re.compile(r"(?<![\w.])([A-Za-z_]\w*)")
#: RK4: stage s is evaluated at the state plus _FAC[s] times the previous stage's derivative
_FAC = {2: "h2", 3: "h2", 4: "dt"}


# The extra hull terms (:mod:`bayesid.models.ship.hullterms`), read from the lane's parameter row at
# run time: one compiled kernel serves every term set (a kernel specialised to each set cost a
# compile of 8-17 s per set, one per candidate term that structure discovery refits). Each term's
# force is the product of the specialised form's factors in its order -- the coefficient times
# q (q L for N), each factor's power in the order of hullterms.FACTORS, then U^(2 - n) for n <= 2
# velocity factors, 1/U for n = 3 and 1/U twice for n = 4 (a surge term; 0 below 1e-9 m/s) --
# multiplied one at a time, left to right, so that the rounding is that of the written-out product. A function of its own, called
# at each stage of each lane: the same loop inlined there doubled the kernel's compile (31 s
# against 16 s, benchmarks/ship_terms.py).
_TERMS_FUNCTION = f'''
@nb.njit(cache=True, error_model="numpy")
def _terms(p, nterm, v, r, L, dl, U, q, qL, X, Y, N):
    """X, Y, N plus the extra hull terms' forces of parameter row p."""
    for kt in range(nterm):
        jt = {NP} + {TERM_WIDTH} * kt
        ft = p[jt]
        at = (qL if ft == 2.0 else q) * p[jt + {TERM_WIDTH - 1}]
        for it in range(int(p[jt + 1])):
            at = at * v
        for it in range(int(p[jt + 2])):
            at = at * (r * L)
        for it in range(int(p[jt + 3])):
            at = at * abs(v)
        for it in range(int(p[jt + 4])):
            at = at * (abs(r) * L)
        for it in range(int(p[jt + 5])):
            at = at * dl
        for it in range(int(p[jt + 6])):
            at = at * abs(dl)
        nvt = int(p[jt + 1]) + int(p[jt + 2]) + int(p[jt + 3]) + int(p[jt + 4])
        if nvt == 0:
            at = at * U
            at = at * U
        elif nvt == 1:
            at = at * U
        elif nvt == 3:
            at = at * (1.0 / U if U > 1e-9 else 0.0)
        elif nvt == 4:
            at = at * (1.0 / U if U > 1e-9 else 0.0)
            at = at * (1.0 / U if U > 1e-9 else 0.0)
        if ft == 0.0:
            X += at
        elif ft == 1.0:
            Y += at
        else:
            N += at
    return X, Y, N
'''
_RHS_TERMS = "X, Y, N = _terms(p, nterm, v, r, L, dl, U, q, qL, X, Y, N)"


def _rhs_statements(stage: int, terms: bool = False) -> list[str]:
    """The right-hand side at RK4 ``stage`` (1..4) as statements on canonical names; the last ones
    assign ``D0``..``D5``, the derivatives of ``x, y, psi, u, v, r``. A statement may span lines
    (a block). ``terms``: with the loop over the extra hull terms of the row."""
    # cross-flow sums i0 = sum_k gw_k f(x_k), i1 = sum_k gw_k x_k f(x_k), f(x) = (v + x r)|v + x r|,
    # x_k = h gx_k: the nodes +-x_j (equal weights) in pairs
    gx, gw = GAUSS_X, GAUSS_W
    quad = []
    for j in range(gx.size // 2):
        x, c = float(-gx[j]), float(gw[j])
        quad += [
            f"xr{j} = h * {x!r} * r",
            f"wp{j} = v + xr{j}",
            f"wm{j} = v - xr{j}",
            f"fp{j} = wp{j} * abs(wp{j})",
            f"fm{j} = wm{j} * abs(wm{j})",
            f"i0 += {c!r} * (fp{j} + fm{j})",
            f"i1 += {c!r} * h * {x!r} * (fp{j} - fm{j})",
        ]
    blocks = [_RHS_HEADING if stage == 1 else _RHS_HEADING_ADD, _RHS_HEAD, _RHS_WIND, _RHS_HULL]
    head = [s for b in blocks for s in _split(b)] + ([_RHS_TERMS] if terms else []) + _split(_RHS_WIND_ADD)
    return head + quad + _split(_RHS_TAIL) + _split(_RHS_ACC)


def _split(block: str) -> list[str]:
    """Top-level statements of a block of source (an indented line belongs to the one above)."""
    out = []
    for line in block.split("\n"):
        if line.startswith(" ") or line.startswith("elif") or line.startswith("else"):
            out[-1] += "\n" + line
        else:
            out.append(line)
    return out


def _rename(stmt: str, fn) -> str:
    """``stmt`` with each name replaced by ``fn(name)`` (attributes such as ``math.sqrt`` kept)."""
    return _IDENT.sub(lambda mt: fn(mt.group(1)), stmt)


def _indent(stmt: str, pad: str) -> str:
    return "\n".join(pad + line for line in stmt.split("\n"))


def _lane_name(lane: int):
    """Renamer of the per-window and per-step statements of ``lane``."""
    return lambda nm: nm if nm in _KEEP else f"{nm}_{lane}"


def _stage_name(stage: int, lane: int):
    """Renamer of the right-hand side at RK4 ``stage`` (1..4) of ``lane``: the state is the
    lane's (stage 1) or the stage's, constants the lane's, locals the stage's; ``cps1``,
    ``sps1`` are stage 1's, ``rprev`` the previous stage's yaw rate and ``fac`` its RK4 factor."""
    special = (
        {}
        if stage == 1
        else {
            "cps1": f"cps_s1_{lane}",
            "sps1": f"sps_s1_{lane}",
            "fac": _FAC[stage],
            "rprev": f"r_{lane}" if stage == 2 else f"r_s{stage - 1}_{lane}",
        }
    )

    def fn(nm):
        if nm in _KEEP:
            return nm
        if nm in special:
            return special[nm]
        if nm in _STATES:
            return f"{nm}_{lane}" if stage == 1 else f"{nm}_s{stage}_{lane}"
        if nm in _ROW_NAMES or nm in _STEP_NAMES:
            return f"{nm}_{lane}"
        return f"{nm}_s{stage}_{lane}"

    return fn


def _kernel_source(lanes: int, terms: bool = False) -> str:
    """Source of ``simulate_windows``, the driver over (row group, window) jobs, and of ``_job``,
    one job with the RK4 step inlined, ``lanes`` rows per job; ``terms``: with the loop over the
    extra hull terms of each row."""
    K = lanes
    P1, P2 = " " * 4, " " * 8
    body = []
    for lane in range(K):
        body += [
            f"b_{lane} = min(g * {K} + {lane}, B - 1)",
            f"live_{lane} = g * {K} + {lane} < B",
            f"p_{lane} = prm[b_{lane}]",
        ]
    row = _split(_ROW)
    for stmt in row:
        for lane in range(K):
            body.append(_rename(stmt, _lane_name(lane)))
    for lane in range(K):
        body += [f"{s}_{lane} = s0[b_{lane}, w, {i}]" for i, s in enumerate(_STATES)]
        body += [
            f"if live_{lane}:",
            f"    status[b_{lane}, w] = 0",
            *(f"    out[b_{lane}, row0, {i}] = {s}_{lane}" for i, s in enumerate(_STATES)),
        ]
    step = ["wn = wind[k, 0]", "we = wind[k, 1]"]
    for stmt in _split(_STEP):
        for lane in range(K):
            step.append(_rename(stmt, _lane_name(lane)))
    for stage in range(1, 5):
        if stage > 1:  # the stage's state (x and y do not enter the right-hand side)
            for lane in range(K):
                step += [
                    f"{s}_s{stage}_{lane} = {s}_{lane} + {_FAC[stage]} * D{i}_s{stage - 1}_{lane}"
                    for i, s in enumerate(_STATES)
                    if i >= 2
                ]
        for stmt in _rhs_statements(stage, terms):
            for lane in range(K):
                step.append(_rename(stmt, _stage_name(stage, lane)))
    for lane in range(K):
        step += [
            f"{s}_{lane} = {s}_{lane} + dt6 * (D{i}_s1_{lane} + 2.0 * D{i}_s2_{lane} + 2.0 * D{i}_s3_{lane}"
            f" + D{i}_s4_{lane})"
            for i, s in enumerate(_STATES)
        ]
        fin = " and ".join(f"math.isfinite({s}_{lane})" for s in _STATES)
        step += [
            f"if live_{lane}:",
            f"    if not ({fin}) or abs(u_{lane}) > 50.0 or abs(v_{lane}) > 50.0 or abs(r_{lane}) > 10.0:",
            f"        status[b_{lane}, w] = 1",
            "        for j in range(row, row1 + 1):",
            "            for i in range(6):",
            f"                out[b_{lane}, j, i] = np.nan",
            f"        live_{lane} = False",
            # a finished lane restarts from its start state (finite; its results are ignored)
            *(f"        {s}_{lane} = s0[b_{lane}, w, {i}]" for i, s in enumerate(_STATES)),
            "    else:",
            *(f"        out[b_{lane}, row, {i}] = {s}_{lane}" for i, s in enumerate(_STATES)),
        ]
    any_live = " or ".join(f"live_{lane}" for lane in range(K))
    return f'''
@nb.njit(cache=True, error_model="numpy")
def _job(g, w, s0, starts, inputs, wind, cur, prm, dt, out, status):
    """Rows g * {K} .. g * {K} + {K - 1} over window w."""
    B = s0.shape[0]
    h2 = 0.5 * dt
    dt6 = dt / 6.0
    row0 = starts[w] + w
    row1 = starts[w + 1] + w
{"    nterm = (prm.shape[1] - " + str(NP) + ") // " + str(TERM_WIDTH) + chr(10) if terms else ""}{chr(10).join(_indent(s, P1) for s in body)}
    row = row0
    for k in range(starts[w], starts[w + 1]):
        row += 1
{chr(10).join(_indent(s, P2) for s in step)}
        if not ({any_live}):
            break


@nb.njit(cache=True, parallel=True)
def simulate_windows(s0, starts, inputs, wind, cur, prm, dt, out, status):
    """As bayesid.models.ship.dynamics.simulate_windows ({K} lane(s) per thread)."""
    W = s0.shape[1]
    for job in nb.prange((s0.shape[0] + {K - 1}) // {K} * W):
        _job(job // W, job % W, s0, starts, inputs, wind, cur, prm, dt, out, status)
'''


_HEADER = '''"""Generated by bayesid.models.ship.kernel ({lanes} lane(s) per thread). Do not edit."""
import math

import numba as nb
import numpy as np

'''


def source(lanes: int = LANES, terms: tuple = ()) -> str:
    """Python source of the generated ship kernel module (``simulate_windows``).

    Parameters
    ----------
    lanes : int, default LANES
        Parameter rows per thread, at least 1.
    terms : tuple, default ()
        The extra hull terms' signature (:func:`bayesid.models.ship.hullterms.signature`). Any
        non-empty set gives the one kernel with the loop over the extra terms, which reads each
        term's degree of freedom, exponents and coefficient from the parameter rows.

    Returns
    -------
    str
        The module's source.

    Raises
    ------
    ValueError
        For ``lanes`` < 1.
    """
    if lanes < 1:
        raise ValueError(f"lanes must be >= 1, got {lanes}")
    return _HEADER.format(lanes=lanes) + (_TERMS_FUNCTION if terms else "") + _kernel_source(lanes, bool(terms))


_MODULES: dict[tuple, object] = {}


def generated(lanes: int = LANES, terms: tuple = ()):
    """The generated kernel module (:func:`bayesid.models.codegen.load_module`; kept per lane
    count and with or without extra terms, as building and hashing the source costs about 11 ms).

    Parameters
    ----------
    lanes : int, default LANES
        Parameter rows per thread.
    terms : tuple, default ()
        The extra hull terms' signature (:func:`bayesid.models.ship.hullterms.signature`): every
        non-empty set shares one module (the terms are read from the rows), compiled once per
        machine and lane count.

    Returns
    -------
    module
        The module, with its ``simulate_windows`` driver.
    """
    key = (lanes, bool(terms))
    mod = _MODULES.get(key)
    if mod is None:
        mod = _MODULES[key] = load_module(source(lanes, terms), "bayesid_shipkernel")
    return mod


def simulate_windows(s0, starts, inputs, wind, cur, prm, dt, out, status, lanes: int = LANES, terms: tuple = ()):
    """The generated kernel with the arguments and results of
    :func:`bayesid.models.ship.dynamics.simulate_windows`.

    Parameters
    ----------
    s0 : ndarray, shape (B, W, 6)
        Window-start states.
    starts : ndarray of int64, shape (W + 1,)
        Step indices of the window starts.
    inputs : ndarray, shape (B, n, 2)
        Rudder (rad) and propeller (rps).
    wind : ndarray, shape (n, 2)
        True wind, m/s, towards north, east.
    cur : ndarray, shape (B, 2)
        Current, m/s.
    prm : ndarray, shape (B, NP + TERM_WIDTH * len(terms))
        Kernel parameter vectors.
    dt : float
        Step, s.
    out : ndarray, shape (B, n + W, 6)
        Output: the states, filled in place.
    status : ndarray of int64, shape (B, W)
        Output: 0 ok, 1 diverged, filled in place.
    lanes : int, default LANES
        Parameter rows per thread.
    terms : tuple, default ()
        The extra hull terms' signature (:func:`bayesid.models.ship.hullterms.signature`).
    """
    generated(lanes, terms).simulate_windows(s0, starts, inputs, wind, cur, prm, dt, out, status)


def kernel(kind: str, terms: tuple = ()):
    """The window driver of a kernel kind.

    Parameters
    ----------
    kind : {"generated", "interpreted"}
        ``"generated"`` (this module) or ``"interpreted"``
        (:func:`bayesid.models.ship.dynamics.simulate_windows`).
    terms : tuple, default ()
        The extra hull terms' signature (:func:`bayesid.models.ship.hullterms.signature`); the
        interpreted kernel reads them from the parameter rows.

    Returns
    -------
    callable
        ``simulate_windows(s0, starts, inputs, wind, cur, prm, dt, out, status)``.

    Raises
    ------
    ValueError
        Naming the option otherwise.
    """
    use_package_threading_layer()
    if kind == "generated":
        return functools.partial(simulate_windows, terms=tuple(terms)) if terms else simulate_windows
    if kind == "interpreted":
        return dynamics.simulate_windows
    raise ValueError(f"kernel must be one of {KINDS}, got {kind!r}")
