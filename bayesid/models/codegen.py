"""Kernels generated from the term table: a compiled right-hand side specialised to the terms a
model actually has.

The interpreted kernel (:mod:`bayesid.models.dynamics`) walks the whole term table at every
right-hand-side evaluation: a loop over the active terms, an inner loop over each term's factor
indices, a feature array, a 6x6 loop for ``M^-1 tau`` and every intermediate in memory. This
module writes, from the same table (:data:`bayesid.data.terms.TERMS`), the Python source of a
right-hand side in which

* each active force term is one unrolled product ``c[j]*u*v``, summed per degree of freedom;
  only the factors some active term uses are computed (the propulsion function eps(eta) only if
  an ``_eps`` term is active);
* the right-hand side is inlined four times into the RK4 step (textually, with renamed locals),
  and the state is twelve scalars (six in the horizontal plane) that stay in registers through
  the stages: no arrays, no allocation, no calls in the step but the libm ones;
* the sines and cosines of the Euler angles come first (a libm call spills every live
  floating-point register, and few are live there) and are shared between kinematics and
  hydrostatics; the sine and cosine of one angle sit side by side, and LLVM already merges them
  into one ``sincos`` call (seen in numba's x86-64 assembly; an explicit ``sincos`` intrinsic
  measures no faster);
* ``M^-1 tau`` is unrolled; the horizontal plane (paper Sec. 4) is its own 3-DOF kernel (states
  x, y, psi, u, v, r; the (u, v, r) block of ``M^-1``; rigid-body terms with w = p = q = 0,
  hydrostatics left out as they vanish at phi = theta = 0), not the 6-DOF one with a zeroed
  inverse;
* each thread advances :data:`LANES` tracks together with their statements interleaved, so the
  CPU overlaps their dependency chains (two in the horizontal plane, one in 6-DOF);
* numba's ``error_model='numpy'``: a division by zero gives inf (flagged as a divergence) rather
  than a Python exception, and costs no test per division.

The equations are those of :mod:`bayesid.models.dynamics` (Furlong et al. 2003, Sec. 2.2,
Eqs. 1, 3-5; ``shared/research/equations.md``), term for term and operation for operation (every
sum and product in the interpreted kernel's order, no fast-math), so generated and interpreted
kernels give bit-identical tracks (compared side by side, they agree to round-off). What is
specialised is the *structure* (which terms are active, the mode):
the coefficient values still come in per track through ``tcoef`` (B, P) = prime coefficient *
0.5 rho L^k, so one generated kernel serves every coefficient vector, every free set with the
same active terms, and every effect that rescales coefficients or switches the cross-flow
integral on. A term is active when its coefficient is non-zero in the vehicle *or free*: a
coefficient that is zero when the kernel is generated but free in the fit is kept.

The generated module is written once per structure to a cache directory (``BAYESID_CACHE`` or
``~/.cache/bayesid``, ``kernels/``), named by the hash of its source, and compiled by numba with
``cache=True``, so the compile is paid once per machine.

Both kernel kinds expose the same two drivers through :func:`kernel`:
``simulate_batch(s0, inputs, dt, sample_every, vp, tcoef, Minv, xs, ws, out, status, fail_step)``
and ``simulate_windows(s0, starts, inputs, exo, ecoef, dt, vp, tcoef, Minv, xs, ws, out, status)``
with the arguments of :func:`bayesid.models.dynamics.simulate_batch` and
:func:`bayesid.models.dynamics.simulate_windows` less the term encoding (``tfac``, ``tdof``).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

from .._numba import sources_digest, use_package_threading_layer
from ..data import terms
from . import dynamics

KINDS = ("generated", "interpreted")
#: Tracks each thread advances together, their statements interleaved, per mode. Measured with
#: benchmarks/simulate.py (NPS AUV II spiral, batch 64, 2 threads): the horizontal plane gains
#: 1.4x from two lanes; in 6-DOF two lanes need more live values than there are registers and
#: lose 20 %.
LANES = {"6dof": 1, "horizontal": 2}

# Scalar name of each feature in the generated source (terms.FEATURES order).
_FEATURE_VAR = {
    "u": "u",
    "v": "v",
    "w": "w",
    "p": "p",
    "q": "q",
    "r": "r",
    "dr": "d_r",
    "ds": "d_s",
    "db": "d_b",
    "eps": "eps",
    "|v|": "abs(v)",
    "|r|": "abs(r)",
    "prop": "prop",
    "|w|": "abs(w)",
    "|q|": "abs(q)",
    "|p|": "abs(p)",
    "1/U": "iU",
}
_STATES = ("x", "y", "z", "ph", "th", "ps", "u", "v", "w", "p", "q", "r")
_PLANE_STATES = (0, 1, 5, 6, 7, 11)  # x, y, psi, u, v, r
_PLANE_DOF = (0, 1, 5)  # X, Y, N


def _hydro_sums(force_names, mode) -> list[str]:
    """Statements ``F0 = ...`` .. ``F5 = ...``: the hydrodynamic force of each degree of freedom,
    each term's product in the interpreted kernel's order (coefficient first, then its factors)."""
    per_dof = {i: [] for i in range(6)}
    for j, name in enumerate(force_names):
        t = terms.term(name)
        if mode == "horizontal" and t.dof not in _PLANE_DOF:
            continue
        factors = [_FEATURE_VAR[f] for f in t.factors]
        per_dof[t.dof].append("*".join([f"c[{j}]"] + factors))
    dofs = _PLANE_DOF if mode == "horizontal" else range(6)
    return [f"F{i} = " + (" + ".join(per_dof[i]) if per_dof[i] else "0.0") for i in dofs]


def _rhs_statements(force_names, mode: str, open_terms: bool = False) -> list[str]:
    """The right-hand side as statements on canonical names -- the states (:data:`_STATES`),
    inputs ``d_r, d_s, d_b, n``, external force ``e0..e5``, the track's ``c`` (tcoef row), ``M``
    (inverse mass matrix), ``vp`` and the :func:`_track_constants`; the last statements assign
    ``D0, D1, ...``, the derivatives of the evolving states. A statement may span lines (a
    block); it is inlined as a whole. An open kernel (``open_terms``) adds the further terms of
    the factor table ``xfac, xdof`` (:func:`_further_terms_source`) after the generated sums."""
    planar = mode == "horizontal"
    dof_terms = [terms.term(n) for n in force_names]
    used = {f for t in dof_terms if not planar or t.dof in _PLANE_DOF for f in t.factors}
    S = []
    a = S.append
    # The sines and cosines first: a libm call spills every live floating-point register, and
    # few are live here.
    a("sps = math.sin(ps)")
    a("cps = math.cos(ps)")
    if planar:
        a("w = 0.0")
        a("p = 0.0")
        a("q = 0.0")
    else:
        a("sph = math.sin(ph)")
        a("cph = math.cos(ph)")
        a("sth = math.sin(th)")
        a("cth = math.cos(th)")
    if "eps" in used or "prop" in used:
        a("n_rad = n * RPM_TO_RAD_S")
        a("uc = vp[VP_UC] * n_rad")
    if "eps" in used:
        # _eps of bayesid.models.dynamics (Healey & Lienard 1993), |u| floored at U_MIN_EPS
        a("ug = u if abs(u) > U_MIN_EPS else (U_MIN_EPS if u >= 0.0 else -U_MIN_EPS)")
        a("eta = uc / ug")
        a("ct = vp[VP_CT] * vp[VP_L] * vp[VP_L] * eta * abs(eta) / 2.0")
        a("sn = 1.0 if n_rad >= 0.0 else -1.0")
        a("su = 1.0 if ug >= 0.0 else -1.0")
        # sn / su of dynamics._eps is +-1 / +-1: the product is the same number, without a division
        a("eps = -1.0 + (sn * su) * (math.sqrt(abs(ct) + 1.0) - 1.0) / epsden")
    if "prop" in used:
        a("prop = uc * abs(uc) - u * abs(u)")
    if "1/U" in used:
        # 1/U of bayesid.models.dynamics.features, U = sqrt(u^2 + v^2 + w^2) floored at U_MIN_EPS
        a("spd = math.sqrt(u * u + v * v + w * w)")
        a("iU = 1.0 / (spd if spd > U_MIN_EPS else U_MIN_EPS)")
    S += _hydro_sums(force_names, mode)
    if open_terms:
        fs = ", ".join(f"F{i}" for i in (_PLANE_DOF if planar else range(6)))
        a(f"{fs} = _further_terms(c, xfac, xdof, u, v, w, p, q, r, d_r, d_s, d_b, n, vp, {fs})")
    if not planar:
        # Hydrostatics (Fossen 1994 pp. 45-46; equations.md "Hydrostatics"); they vanish at
        # phi = theta = 0 and are left out of the horizontal plane.
        a("F0 += -wb * sth")
        a("F1 += wb * cth * sph")
        a("F2 += wb * cth * cph")
        a("F3 += hy * cth * cph - hz * cth * sph")
        a("F4 += -hx * cth * cph - hz * sth")
        a("F5 += hx * cth * sph + hy * sth")
    # Cross-flow drag strip sum (Feldman 1979 as in MSS), on when vp[VP_XFLOW] != 0.
    heave = "" if planar else ("\n            F2 -= g * wl\n            F4 += g * wl * xi")
    a(
        "if vp[VP_XFLOW] != 0.0:\n"
        "    half_rho = 0.5 * vp[VP_RHO]\n"
        "    for i in range(xs.shape[0]):\n"
        "        xi = xs[i]\n"
        "        vl = v + xi * r\n"
        "        wl = w - xi * q\n"
        "        ucf = math.sqrt(vl * vl + wl * wl)\n"
        "        if ucf > 1e-12:\n"
        "            g = (vp[VP_CDYH] * vl * vl + vp[VP_CDZB] * wl * wl) * half_rho * ws[i] / ucf\n"
        "            F1 -= g * vl\n"
        "            F5 -= g * vl * xi" + heave
    )
    # Rigid-body velocity terms on the right-hand side (paper Eq. 1; equations.md).
    if planar:
        a("F0 -= m * (-v * r + w * q - xg * (q * q + r * r) + yg * p * q + zg * p * r)")
        a("F1 -= m * (-w * p + u * r - yg * (r * r + p * p) + zg * q * r + xg * q * p)")
        a("F5 -= m * (xg * (-w * p + u * r) - yg * (-v * r + w * q))")
    else:
        a("F0 -= m * (-v * r + w * q - xg * (q * q + r * r) + yg * p * q + zg * p * r)")
        a("F1 -= m * (-w * p + u * r - yg * (r * r + p * p) + zg * q * r + xg * q * p)")
        a("F2 -= m * (-u * q + v * p - zg * (p * p + q * q) + xg * r * p + yg * r * q)")
        a(
            "F3 -= (Izy * q * r - p * q * Ixz + (r * r - q * q) * Iyz + p * r * Ixy"
            " + m * (yg * (-u * q + v * p) - zg * (-w * p + u * r)))"
        )
        a(
            "F4 -= (Ixz_ * r * p - q * r * Ixy + (p * p - r * r) * Ixz + q * p * Iyz"
            " + m * (zg * (-v * r + w * q) - xg * (-u * q + v * p)))"
        )
        a(
            "F5 -= (Iyx * p * q - r * p * Iyz + (q * q - p * p) * Ixy + r * q * Ixz"
            " + m * (xg * (-w * p + u * r) - yg * (-v * r + w * q)))"
        )
    dofs = _PLANE_DOF if planar else range(6)
    for i in dofs:
        a(f"F{i} += e{i}")
    # M nu_dot = tau: the accelerations (the (u, v, r) block of M^-1 in the horizontal plane)
    for i in dofs:
        a(f"A{i} = 0.0 + " + " + ".join(f"M[{i}, {j}] * F{j}" for j in dofs))
    # zyx Euler kinematics (Fossen 1994, Eq. 2.18/2.28)
    if planar:
        kin = ["cps * u - sps * v", "sps * u + cps * v", "r"]
        acc = ["A0", "A1", "A5"]
    else:
        kin = [
            "cps * cth * u + (cps * sth * sph - sps * cph) * v + (cps * sth * cph + sps * sph) * w",
            "sps * cth * u + (sps * sth * sph + cps * cph) * v + (sps * sth * cph - cps * sph) * w",
            "-sth * u + cth * sph * v + cth * cph * w",
            "p + (sph * q + cph * r) * sth / cth",
            "cph * q - sph * r",
            "(sph * q + cph * r) / cth",
        ]
        acc = [f"A{i}" for i in range(6)]
    for i, e in enumerate(kin + acc):
        a(f"D{i} = {e}")
    return S


def _track_constants(force_names, mode: str) -> list[str]:
    """Statements computed once per step from the vehicle parameters ``vp`` alone (hoisted out
    of the four right-hand sides; the same expressions as the interpreted kernel's, so the same
    numbers)."""
    K = ["W = vp[VP_W]", "Bu = vp[VP_B]", "xg = vp[VP_XG]", "yg = vp[VP_YG]", "zg = vp[VP_ZG]", "m = vp[VP_M]"]
    if any("eps" in terms.term(n).factors for n in force_names):
        K += ["ct1 = vp[VP_CT] * vp[VP_L] * vp[VP_L] / 2.0", "epsden = math.sqrt(ct1 + 1.0) - 1.0"]
    if mode != "horizontal":
        K += [
            "xb = vp[VP_XB]",
            "yb = vp[VP_YB]",
            "zb = vp[VP_ZB]",
            "wb = W - Bu",
            "hx = xg * W - xb * Bu",
            "hy = yg * W - yb * Bu",
            "hz = zg * W - zb * Bu",
            "Ix = vp[VP_IX]",
            "Iy = vp[VP_IY]",
            "Iz = vp[VP_IZ]",
            "Ixy = vp[VP_IXY]",
            "Iyz = vp[VP_IYZ]",
            "Ixz = vp[VP_IXZ]",
            "Izy = Iz - Iy",
            "Ixz_ = Ix - Iz",
            "Iyx = Iy - Ix",
        ]
    return K


# Names the inliner leaves alone: Python, the math module, the kernel constants, shared arrays.
_KEEP = {
    "math",
    "abs",
    "range",
    "if",
    "else",
    "for",
    "in",
    "not",
    "and",
    "or",
    "min",
    "max",
    "xs",
    "ws",
    "RPM_TO_RAD_S",
    "U_MIN_EPS",
    "OK",
    "NONFINITE",
    "OUT_OF_BOUNDS",
    "_further_terms",
    "xfac",
    "xdof",
}
_IDENT = re.compile(r"(?<![\w.])([A-Za-z_]\w*)")


def _rename(stmt: str, mapping: dict, suffix: str) -> str:
    """``stmt`` with each name replaced by ``mapping[name]``, or by ``name + suffix`` for a local
    (a name not in :data:`_KEEP` nor a ``VP_`` constant)."""

    def sub(mt):
        name = mt.group(1)
        if name in mapping:
            return mapping[name]
        if name in _KEEP or name.startswith("VP_"):
            return name
        return name + suffix

    return _IDENT.sub(sub, stmt)


def _indent(stmt: str, pad: str) -> str:
    return "\n".join(pad + line for line in stmt.split("\n"))


def _step_source(force_names, mode: str, lanes: int, open_terms: bool = False) -> str:
    """Source of ``_step``: one classical RK4 step of ``lanes`` independent tracks on scalars, the
    right-hand side inlined four times and the lanes interleaved statement by statement (their
    dependency chains overlap in the CPU; no arrays, no allocation). Inputs and external force
    are held over the step (zero-order hold), as in :func:`bayesid.models.dynamics.rk4_step`.
    An open kernel's step also takes the further terms' factor table ``xfac, xdof``."""
    body = _rhs_statements(force_names, mode, open_terms)
    shared = "dt, xs, ws, xfac, xdof" if open_terms else "dt, xs, ws"
    st = [_STATES[i] for i in (_PLANE_STATES if mode == "horizontal" else range(12))]
    per_lane = st + ["d_r", "d_s", "d_b", "n", "e0", "e1", "e2", "e3", "e4", "e5", "c", "M", "vp"]
    args = [f"{a}_{l}" for l in range(lanes) for a in per_lane]
    L = ["@nb.njit(cache=True, error_model='numpy')", f"def _step({', '.join(args)}, {shared}):", "    h = 0.5 * dt"]
    consts = _track_constants(force_names, mode)
    hoisted = sorted({_IDENT.match(c).group(1) for c in consts})
    for c in consts:
        for lane in range(lanes):
            L.append("    " + _rename(c, {"vp": f"vp_{lane}"}, f"_k{lane}"))
    for stage, (prev, fac) in enumerate(((None, None), (1, "h"), (2, "h"), (3, "dt")), start=1):
        for lane in range(lanes):
            if prev is not None:
                for i, s in enumerate(st):
                    L.append(f"    {s}_s{stage}_{lane} = {s}_{lane} + {fac} * D{i}_s{prev}_{lane}")
        maps = []
        for lane in range(lanes):
            mp = {a: f"{a}_{lane}" for a in per_lane}
            mp.update({k: f"{k}_k{lane}" for k in hoisted})
            if prev is not None:
                mp.update({s: f"{s}_s{stage}_{lane}" for s in st})
            maps.append(mp)
        for stmt in body:
            for lane in range(lanes):
                L.append(_indent(_rename(stmt, maps[lane], f"_s{stage}_{lane}"), "    "))
    out = [
        f"{s}_{lane} + dt * (D{i}_s1_{lane} + 2.0 * D{i}_s2_{lane} + 2.0 * D{i}_s3_{lane} + D{i}_s4_{lane}) / 6.0"
        for lane in range(lanes)
        for i, s in enumerate(st)
    ]
    L.append("    return (" + ",\n            ".join(out) + ",)")
    return "\n".join(L)


def _check_source(idx, lane: int, pad: str) -> str:
    """Statement setting ``flag_<lane>``: dynamics.check_state on the lane's evolving states."""
    names = [f"{_STATES[i]}_{lane}" for i in idx]
    fin = " and ".join(f"math.isfinite({s})" for s in names)
    oob = [f"abs({_STATES[i]}_{lane}) > vmax_{lane}" for i in idx if 6 <= i <= 8]
    oob += [f"abs({_STATES[i]}_{lane}) > wmax_{lane}" for i in idx if 9 <= i <= 11]
    if 4 in idx:
        oob.append(f"abs(th_{lane}) > thmax_{lane}")
    return (
        f"{pad}flag_{lane} = OK\n"
        f"{pad}if not ({fin}):\n"
        f"{pad}    flag_{lane} = NONFINITE\n"
        f"{pad}elif {' or '.join(oob)}:\n"
        f"{pad}    flag_{lane} = OUT_OF_BOUNDS"
    )


_P12 = "        "
_P16 = _P12 + "    "


class _LaneCode:
    """Source fragments shared by the two drivers: ``lanes`` tracks advanced together per thread
    through :func:`_step`, over the states of ``mode``."""

    def __init__(self, mode: str, lanes: int, open_terms: bool = False):
        self.mode, self.K = mode, lanes
        # an open kernel's drivers take the further terms' factor table last (Open)
        self.more = ", xfac, xdof" if open_terms else ""
        self.idx = list(_PLANE_STATES if mode == "horizontal" else range(12))
        self.any_live = " or ".join(f"live_{l}" for l in range(lanes))

    def step_call(self, inp: str, ext: str) -> str:
        """The call of ``_step`` advancing every lane one step (``inp``, ``ext``: the inputs'
        and the external forces' expressions, formatted with the lane ``l`` and index ``j``)."""
        args = []
        for l in range(self.K):
            args += [f"{_STATES[i]}_{l}" for i in self.idx]
            args += [inp.format(l=l, j=j) for j in range(4)] + [ext.format(l=l, j=j) for j in range(6)]
            args += [f"c_{l}", f"M_{l}", f"vp_{l}"]
        lhs = ", ".join(f"{_STATES[i]}_{l}" for l in range(self.K) for i in self.idx)
        return f"({lhs},) = _step({', '.join(args)}, dt, xs, ws{self.more})"

    def reset(self, l: int, src: str, pad: str) -> str:
        """A finished lane restarts from its start state (finite, ignored)."""
        return "\n".join(f"{pad}{_STATES[i]}_{l} = {src.format(l=l, i=i)}" for i in self.idx)

    def lane_setup(self, l, vp_row, extra, status_lines, rows, start) -> str:
        """Per lane before the steps: its row ``b_l`` (the last row again for a padding lane),
        coefficients, inverse mass matrix, parameters; a live lane's outputs start as ``start``."""
        K = self.K
        return (
            f"{_P12}b_{l} = min(g * {K} + {l}, B - 1)\n"
            f"{_P12}live_{l} = g * {K} + {l} < B\n"
            f"{_P12}c_{l} = tcoef[b_{l}]\n"
            f"{_P12}M_{l} = Minv[b_{l}]\n"
            f"{_P12}vp_{l} = {vp_row.format(l=l)}\n"
            + "".join(f"{_P12}{line.format(l=l)}\n" for line in extra)
            + f"{_P12}vmax_{l}, wmax_{l}, thmax_{l} = vp_{l}[VP_VMAX], vp_{l}[VP_WMAX], vp_{l}[VP_THMAX]\n"
            f"{_P12}if live_{l}:\n"
            + "".join(f"{_P16}{line.format(l=l)}\n" for line in status_lines)
            + f"{_P16}for j in range({rows}):\n"
            f"{_P16}    for i in range(12):\n"
            f"{_P16}        out[b_{l}, j, i] = {start.format(l=l)}"
        )

    def after_step(self, l, flagged, nan_rows, start, store) -> str:
        """Per lane after a step: check, on divergence record it, NaN-fill ``nan_rows`` and
        restart the lane from ``start``; else store the state under ``store``."""
        return (
            f"{_P16}if live_{l}:\n" + _check_source(self.idx, l, _P16 + "    ") + "\n"
            f"{_P16}    if flag_{l} != OK:\n"
            + "".join(f"{_P16}        {line.format(l=l)}\n" for line in flagged)
            + f"{_P16}        for j in range({nan_rows}):\n"
            f"{_P16}            for i in range(12):\n"
            f"{_P16}                out[b_{l}, j, i] = np.nan\n"
            f"{_P16}        live_{l} = False\n" + self.reset(l, start, _P16 + "        ") + "\n"
            f"{_P16}    {store}:\n"
            + "\n".join(f"{_P16}        out[b_{l}, row, {i}] = {_STATES[i]}_{l}" for i in self.idx)
        )


def _batch_source(h: _LaneCode) -> str:
    """Source of the driver over a batch of coefficient vectors (one track)."""
    K, idx = h.K, h.idx
    load_b = "\n".join(f"{_P12}{_STATES[i]}_{l} = s0[b_{l}, {i}]" for l in range(K) for i in idx)
    lanes_b = "\n".join(
        h.lane_setup(l, "vp", [], ["status[b_{l}] = OK", "fail_step[b_{l}] = -1"], "n_out", "s0[b_{l}, i]")
        for l in range(K)
    )
    after_b = [
        h.after_step(
            l,
            ["status[b_{l}] = flag_{l}", "fail_step[b_{l}] = k"],
            "(k + 1 + sample_every - 1) // sample_every, n_out",
            "s0[b_{l}, {i}]",
            "elif store",
        )
        for l in range(K)
    ]
    return f'''
@nb.njit(cache=True, parallel=True, error_model='numpy')
def simulate_batch(s0, inputs, dt, sample_every, vp, tcoef, Minv, xs, ws, out, status, fail_step{h.more}):
    """As bayesid.models.dynamics.simulate_batch (generated: {h.mode}, {K} lane(s) per thread)."""
    B = s0.shape[0]
    n_steps = inputs.shape[0]
    n_out = out.shape[1]
    for g in nb.prange((B + {K - 1}) // {K}):
{lanes_b}
{load_b}
        for k in range(n_steps):
            {h.step_call("inputs[k, {j}]", "0.0")}
            store = (k + 1) % sample_every == 0
            row = (k + 1) // sample_every
{chr(10).join(after_b)}
            if not ({h.any_live}):
                break
'''


def _windows_source(h: _LaneCode) -> str:
    """Source of the driver over the windows of one record (multiple shooting)."""
    K, idx = h.K, h.idx
    load_w = "\n".join(f"{_P12}{_STATES[i]}_{l} = s0[b_{l}, w, {i}]" for l in range(K) for i in idx)
    lanes_w = "\n".join(
        h.lane_setup(
            l, "vp_all[b_{l}]", ["E_{l} = ecoef[b_{l}]"], ["status[b_{l}, w] = OK"], "row0, row1 + 1", "s0[b_{l}, w, i]"
        )
        for l in range(K)
    )
    ext_w = (
        "\n".join(f"{_P16}x{i}_{l} = 0.0" for l in range(K) for i in range(6))
        + "\n"
        + f"{_P16}for j in range(Kx):\n"
        + "\n".join(
            f"{_P16}    g{l} = exo[b_{l}, k, j]\n"
            + "\n".join(f"{_P16}    x{i}_{l} += g{l} * E_{l}[j, {i}]" for i in range(6))
            for l in range(K)
        )
    )
    after_w = [
        h.after_step(l, ["status[b_{l}, w] = flag_{l}"], "row, row1 + 1", "s0[b_{l}, w, {i}]", "else") for l in range(K)
    ]
    return f'''
@nb.njit(cache=True, parallel=True, error_model='numpy')
def simulate_windows(s0, starts, inputs, exo, ecoef, dt, vp_all, tcoef, Minv, xs, ws, out, status{h.more}):
    """As bayesid.models.dynamics.simulate_windows (generated: {h.mode}, {K} lane(s) per thread)."""
    B = s0.shape[0]
    W = starts.shape[0] - 1
    Kx = exo.shape[2]
    G = (B + {K - 1}) // {K}
    for job in nb.prange(G * W):
        g = job // W
        w = job % W
        row0 = starts[w] + w
        row1 = starts[w + 1] + w
{lanes_w}
{load_w}
        row = row0
        for k in range(starts[w], starts[w + 1]):
{ext_w}
            {h.step_call("inputs[b_{l}, k, {j}]", "x{j}_{l}")}
            row += 1
{chr(10).join(after_w)}
            if not ({h.any_live}):
                break
'''


def _drivers_source(mode: str, lanes: int, open_terms: bool = False) -> str:
    """Source of the two drivers (the batch over coefficient vectors and the windows), each
    thread advancing ``lanes`` tracks together through :func:`_step`."""
    h = _LaneCode(mode, lanes, open_terms)
    return _batch_source(h) + _windows_source(h)


_HEADER = '''"""Generated by bayesid.models.codegen for {n} active force terms, mode {mode}, {lanes} lane(s). Do not edit.

Terms: {names}
"""
import math

import numba as nb
import numpy as np

from bayesid.models.dynamics import (OK, NONFINITE, OUT_OF_BOUNDS, RPM_TO_RAD_S, U_MIN_EPS, VP_B, VP_CDYH,
                                     VP_CDZB, VP_CT, VP_IX, VP_IXY, VP_IXZ, VP_IY, VP_IYZ, VP_IZ, VP_L, VP_M,
                                     VP_RHO, VP_THMAX, VP_UC, VP_VMAX, VP_W, VP_WMAX, VP_XB, VP_XFLOW, VP_XG,
                                     VP_YB, VP_YG, VP_ZB, VP_ZG)

'''


def _further_terms_source(n_base: int, mode: str) -> str:
    """Source of ``_further_terms``, the open kernel's loop over the terms the kernel was not
    generated for: the term table's encoding (:func:`bayesid.data.terms.factor_table`: feature
    indices, degree of freedom) passed at run time, each coefficient in ``c[n_base + j]``. Each
    product is formed coefficient first, then its factors in order, and added to its degree of
    freedom after the generated terms -- the order of the interpreted kernel when the further
    terms come last in their degree of freedom, which :class:`Open` checks."""
    dofs = _PLANE_DOF if mode == "horizontal" else tuple(range(6))
    fs = ", ".join(f"F{i}" for i in dofs)
    add = "\n".join(
        f"        {'if' if k == 0 else 'elif'} d == {i}:\n            F{i} += prod" for k, i in enumerate(dofs)
    )
    # the features that are a state or input or its magnitude, as the generated sums read them
    simple = "".join(
        f"    if i == {k}:\n        return {_FEATURE_VAR[f]}\n"
        for k, f in enumerate(terms.FEATURES)
        if f not in ("1", "eps", "prop", "1/U")
    )
    return f'''@nb.njit(cache=True, error_model='numpy', inline='always')
def _feature(i, u, v, w, p, q, r, d_r, d_s, d_b, n, vp):
    """Feature i of bayesid.data.terms.FEATURES, computed as the generated right-hand side does."""
{simple}    if i == 17:
        spd = math.sqrt(u * u + v * v + w * w)
        return 1.0 / (spd if spd > U_MIN_EPS else U_MIN_EPS)
    n_rad = n * RPM_TO_RAD_S
    uc = vp[VP_UC] * n_rad
    if i == 13:
        return uc * abs(uc) - u * abs(u)
    # i == 10: eps(eta) (Healey & Lienard 1993), |u| floored at U_MIN_EPS
    ct1 = vp[VP_CT] * vp[VP_L] * vp[VP_L] / 2.0
    epsden = math.sqrt(ct1 + 1.0) - 1.0
    ug = u if abs(u) > U_MIN_EPS else (U_MIN_EPS if u >= 0.0 else -U_MIN_EPS)
    eta = uc / ug
    ct = vp[VP_CT] * vp[VP_L] * vp[VP_L] * eta * abs(eta) / 2.0
    sn = 1.0 if n_rad >= 0.0 else -1.0
    su = 1.0 if ug >= 0.0 else -1.0
    return -1.0 + (sn * su) * (math.sqrt(abs(ct) + 1.0) - 1.0) / epsden


@nb.njit(cache=True, error_model='numpy', inline='always')
def _further_terms(c, xfac, xdof, u, v, w, p, q, r, d_r, d_s, d_b, n, vp, {fs}):
    """The forces plus the further terms (factor table xfac, xdof; coefficients c[{n_base}:])."""
    for j in range(xdof.shape[0]):
        prod = c[{n_base} + j]
        for k in range(xfac.shape[1]):
            i = xfac[j, k]
            if i == 0:
                break
            prod *= _feature(i, u, v, w, p, q, r, d_r, d_s, d_b, n, vp)
        d = xdof[j]
{add}
    return {fs}


'''


def source(force_names, mode: str = "6dof", lanes: int | None = None, open_terms: bool = False) -> str:
    """Python source of the generated kernel module for a model's active force terms.

    Parameters
    ----------
    force_names : sequence of str
        The active force terms (the order of the ``tcoef`` columns).
    mode : {"6dof", "horizontal"}, default "6dof"
        Degrees of freedom.
    lanes : int, optional
        Tracks each thread advances together; default :data:`LANES` of the mode.
    open_terms : bool, default False
        Generate an open kernel (:class:`Open`): its drivers also take the factor table of
        further terms, ``xfac, xdof``, whose coefficients follow the generated ones in ``tcoef``.

    Returns
    -------
    str
        The module's source.

    Raises
    ------
    ValueError
        Unknown mode, ``lanes`` < 1, or an acceleration term among ``force_names``.
    UnknownCoefficientError
        A name not in the term table.
    """
    if mode not in LANES:
        raise ValueError(f"mode must be '6dof' or 'horizontal', got {mode!r}")
    lanes = LANES[mode] if lanes is None else int(lanes)
    if lanes < 1:
        raise ValueError(f"lanes must be >= 1, got {lanes}")
    force_names = list(force_names)
    terms.factor_table(force_names)  # raises on an acceleration term or an unknown name
    head = _HEADER.format(n=len(force_names), mode=mode, lanes=lanes, names=" ".join(force_names) or "(none)")
    if open_terms:
        head = head.replace(" Do not edit.", " Open: further terms at run time. Do not edit.", 1)
        head = head.rstrip("\n") + "\n\n\n" + _further_terms_source(len(force_names), mode)
    return head + _step_source(force_names, mode, lanes, open_terms) + "\n\n" + _drivers_source(mode, lanes, open_terms)


def cache_dir() -> Path:
    """Directory of the generated kernel modules, created if needed.

    Returns
    -------
    Path
        ``$BAYESID_CACHE/kernels`` or ``~/.cache/bayesid/kernels`` (``$XDG_CACHE_HOME``
        respected); a temporary directory if neither is writable.
    """
    root = os.environ.get("BAYESID_CACHE")
    if root is None:
        root = os.path.join(os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "bayesid")
    d = Path(root) / "kernels"
    try:
        d.mkdir(parents=True, exist_ok=True)
        probe = d / f".probe{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError:
        d = Path(tempfile.gettempdir()) / f"bayesid-kernels-{os.getuid() if hasattr(os, 'getuid') else 0}"
        d.mkdir(parents=True, exist_ok=True)
    return d


_LOADED: dict[str, object] = {}


def load_module(src: str, prefix: str):
    """Import generated source as a module named ``<prefix>_<hash>``: written once to
    :func:`cache_dir` (atomically; a concurrent process sees the old or the whole new file) and
    imported once per process, so numba's ``cache=True`` keeps its compiled code between
    processes. Shared by this module and :mod:`bayesid.models.ship.kernel`. The hash covers the
    package's model sources too (:func:`bayesid._numba.sources_digest`): a generated module imports
    their constants, which numba freezes into its cache, so a change there names a new module.

    Parameters
    ----------
    src : str
        The module's source.
    prefix : str
        Start of the module's name.

    Returns
    -------
    module
        The imported module.
    """
    name = f"{prefix}_{hashlib.sha256((src + sources_digest()).encode()).hexdigest()[:16]}"
    mod = _LOADED.get(name)
    if mod is not None:
        return mod
    path = cache_dir() / f"{name}.py"
    if not path.exists() or path.read_text() != src:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(src)
        os.replace(tmp, path)
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    _LOADED[name] = mod
    return mod


def generated(force_names, mode: str = "6dof", lanes: int | None = None, open_terms: bool = False):
    """The generated kernel module (:func:`load_module` of :func:`source`).

    Parameters
    ----------
    force_names : sequence of str
        The active force terms.
    mode : {"6dof", "horizontal"}, default "6dof"
        Degrees of freedom.
    lanes : int, optional
        Tracks each thread advances together; default :data:`LANES` of the mode.
    open_terms : bool, default False
        The open kernel of these terms (:class:`Open`).

    Returns
    -------
    module
        The module, with the drivers ``simulate_batch`` and ``simulate_windows``.
    """
    return load_module(source(force_names, mode, lanes, open_terms), "bayesid_kernel")


def further_terms_last(force_names, further) -> bool:
    """Whether every term of ``further`` comes after every other term of its degree of freedom in
    ``force_names``: then the open kernel of the others (:class:`Open`), which adds the further
    terms after its generated sums, adds in the interpreted kernel's order, and its tracks are the
    same bits as those of the kernel generated for all of ``force_names``.

    Parameters
    ----------
    force_names : sequence of str
        The active force terms, in the order of the ``tcoef`` columns.
    further : sequence of str
        Some of them.

    Returns
    -------
    bool
        True when the open kernel adds every further term in the interpreted kernel's order.
    """
    further = set(further)
    last_base = {}
    for j, n in enumerate(force_names):
        if n not in further:
            last_base[terms.term(n).dof] = j
    return all(j > last_base.get(terms.term(n).dof, -1) for j, n in enumerate(force_names) if n in further)


class Open:
    """A kernel generated for a model's base terms that takes further terms at run time.

    Structure discovery refits a model once per candidate term, each a coefficient that is zero in
    the vehicle and free: a kernel generated per candidate costs a numba compile each (about 10 s
    on a 2-core machine), far more than most refits. The open kernel is generated and compiled
    once per base: the candidate's product is formed by a loop over its factors
    (:func:`_further_terms_source`) and added after the generated terms of its degree of freedom,
    which is the interpreted kernel's order when :func:`further_terms_last` holds, so the tracks
    are the same bits.

    Parameters
    ----------
    force_names : sequence of str
        The active force terms (the order of the ``tcoef`` columns).
    further : sequence of str
        The ones the kernel takes at run time; the others are generated.
    mode : {"6dof", "horizontal"}
        Degrees of freedom.

    Raises
    ------
    ValueError
        When a further term is not among ``force_names``.
    """

    def __init__(self, force_names, further, mode: str):
        force_names, further = list(force_names), list(further)
        missing = [n for n in further if n not in force_names]
        if missing:
            raise ValueError(f"further terms {missing} are not among the active force terms")
        base = [n for n in force_names if n not in further]
        further = [n for n in force_names if n in further]  # in column order
        self.module = generated(base, mode, open_terms=True)
        order = [force_names.index(n) for n in base + further]
        self.perm = None if order == list(range(len(order))) else np.array(order, dtype=np.int64)
        self.xfac, self.xdof = terms.factor_table(further)

    def _columns(self, tcoef):
        return tcoef if self.perm is None else np.ascontiguousarray(tcoef[:, self.perm])

    def simulate_batch(self, s0, inputs, dt, sample_every, vp, tcoef, Minv, xs, ws, out, status, fail_step):
        """The generated ``simulate_batch`` with the further terms' factor table.

        Parameters
        ----------
        s0, inputs, dt, sample_every, vp, tcoef, Minv, xs, ws, out, status, fail_step : object
            As in :func:`bayesid.models.dynamics.simulate_batch`.
        """
        self.module.simulate_batch(
            s0,
            inputs,
            dt,
            sample_every,
            vp,
            self._columns(tcoef),
            Minv,
            xs,
            ws,
            out,
            status,
            fail_step,
            self.xfac,
            self.xdof,
        )

    def simulate_windows(self, s0, starts, inputs, exo, ecoef, dt, vp, tcoef, Minv, xs, ws, out, status):
        """The generated ``simulate_windows`` with the further terms' factor table.

        Parameters
        ----------
        s0, starts, inputs, exo, ecoef, dt, vp, tcoef, Minv, xs, ws, out, status : object
            As in :func:`bayesid.models.dynamics.simulate_windows`.
        """
        self.module.simulate_windows(
            s0,
            starts,
            inputs,
            exo,
            ecoef,
            dt,
            vp,
            self._columns(tcoef),
            Minv,
            xs,
            ws,
            out,
            status,
            self.xfac,
            self.xdof,
        )


class Interpreted:
    """The interpreted kernel behind the same two drivers as a generated one (the baseline of
    ``benchmarks/simulate.py`` and the oracle the generated kernels are checked against).

    The drivers take the arguments of :func:`bayesid.models.dynamics.simulate_batch` and
    :func:`bayesid.models.dynamics.simulate_windows` less the term encoding.

    Parameters
    ----------
    force_names : sequence of str
        The active force terms (the order of the ``tcoef`` columns).
    """

    def __init__(self, force_names):
        self.tfac, self.tdof = terms.factor_table(list(force_names))

    def simulate_batch(self, s0, inputs, dt, sample_every, vp, tcoef, Minv, xs, ws, out, status, fail_step):
        """:func:`bayesid.models.dynamics.simulate_batch` with this kernel's term encoding.

        Parameters
        ----------
        s0, inputs, dt, sample_every, vp, tcoef, Minv, xs, ws, out, status, fail_step : object
            As in :func:`bayesid.models.dynamics.simulate_batch`.
        """
        dynamics.simulate_batch(
            s0, inputs, dt, sample_every, vp, self.tfac, self.tdof, tcoef, Minv, xs, ws, out, status, fail_step
        )

    def simulate_windows(self, s0, starts, inputs, exo, ecoef, dt, vp, tcoef, Minv, xs, ws, out, status):
        """:func:`bayesid.models.dynamics.simulate_windows` with this kernel's term encoding.

        Parameters
        ----------
        s0, starts, inputs, exo, ecoef, dt, vp, tcoef, Minv, xs, ws, out, status : object
            As in :func:`bayesid.models.dynamics.simulate_windows`.
        """
        dynamics.simulate_windows(
            s0, starts, inputs, exo, ecoef, dt, vp, self.tfac, self.tdof, tcoef, Minv, xs, ws, out, status
        )


def kernel(force_names, mode: str = "6dof", kind: str = "generated", further=()):
    """The compiled drivers for a model's active force terms.

    Parameters
    ----------
    force_names : sequence of str
        The active force terms.
    mode : {"6dof", "horizontal"}, default "6dof"
        Degrees of freedom.
    kind : {"generated", "interpreted"}, default "generated"
        ``"generated"`` (this module) or ``"interpreted"`` (:mod:`bayesid.models.dynamics`).
    further : sequence of str, default ()
        Terms a generated kernel may take at run time (:class:`Open`) rather than generate: the
        simulator passes the free coefficients that are zero in the vehicle (a discovery
        candidate). Used when :func:`further_terms_last` holds, so the tracks are the same bits
        either way; otherwise every term is generated.

    Returns
    -------
    module, Open or Interpreted
        An object with the drivers ``simulate_batch`` and ``simulate_windows``.

    Raises
    ------
    ValueError
        Unknown ``kind`` or ``mode``.
    """
    if mode not in LANES:
        raise ValueError(f"mode must be '6dof' or 'horizontal', got {mode!r}")
    use_package_threading_layer()
    if kind == "generated":
        if len(further) and further_terms_last(force_names, further):
            return Open(force_names, further, mode)
        return generated(force_names, mode)
    if kind == "interpreted":
        return Interpreted(force_names)
    raise ValueError(f"kernel must be one of {KINDS}, got {kind!r}")
