"""The C library's ``sincos`` for the generated kernels: a sine and a cosine of one angle in one call.

numba lowers ``math.sin`` and ``math.cos`` to two calls of the C library's ``sin`` and ``cos``.
The 6-DOF kernel takes the sine and cosine of three Euler angles at each of four RK4 stages, and
these calls were about 37 % of its time. glibc's ``sincos`` shares the argument reduction and
returns, bit for bit, what ``sin`` and ``cos`` return (glibc's ``s_sincos.c`` calls the same
internal routines; checked at import on a table of angles, see :data:`HAVE_SINCOS`), so a kernel
using it stays bit-identical to one that calls ``math.sin`` and ``math.cos``.

:func:`sincos` is a numba intrinsic: usable only inside ``@njit`` code. Where the C library has no
``sincos`` or its results differ from ``math.sin``/``math.cos`` in the last bit (another libm),
:data:`HAVE_SINCOS` is False and :mod:`bayesid.models.codegen` writes ``math.sin``/``math.cos``;
``BAYESID_SINCOS=0`` in the environment forces that.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import math
import os

import numpy as np
from llvmlite import binding as llvm
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


def _probe() -> bool:
    """True when the process's C library has ``sincos`` and it agrees bit for bit with the
    ``sin`` and ``cos`` numba calls, on angles from 1e-8 to 1e4 rad of both signs."""
    if os.environ.get("BAYESID_SINCOS", "1") == "0":      # to measure or rule out the difference
        return False
    name = ctypes.util.find_library("m")
    try:
        lib = ctypes.CDLL(name)
        f = lib.sincos
    except (OSError, AttributeError, TypeError):
        return False
    f.restype = None
    f.argtypes = [ctypes.c_double, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double)]
    s, c = ctypes.c_double(), ctypes.c_double()
    rng = np.random.default_rng(0)
    xs = np.concatenate([rng.normal(0.0, 1.0, 400), rng.uniform(-7.0, 7.0, 400), rng.normal(0.0, 1e3, 200),
                         np.geomspace(1e-8, 1e4, 200), [0.0, -0.0, math.pi / 2, math.pi, 1e300]])
    for x in np.concatenate([xs, -xs]):
        f(float(x), ctypes.byref(s), ctypes.byref(c))
        if (s.value, c.value) != (math.sin(x), math.cos(x)):
            return False
    if name:
        llvm.load_library_permanently(name)     # so numba's JIT resolves the symbol
    return True


#: Whether the generated kernels call ``sincos`` (True with glibc).
HAVE_SINCOS = _probe()


@intrinsic
def sincos(typingctx, x):
    """``(sin(x), cos(x))`` of a float64 ``x`` (rad) by one call of the C library's ``sincos``;
    bit-identical to ``(math.sin(x), math.cos(x))`` where :data:`HAVE_SINCOS`."""
    if not isinstance(x, types.Float):
        return None
    sig = types.UniTuple(types.float64, 2)(types.float64)

    def codegen(context, builder, signature, args):
        dbl = ir.DoubleType()
        fnty = ir.FunctionType(ir.VoidType(), [dbl, dbl.as_pointer(), dbl.as_pointer()])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "sincos")
        s = cgutils.alloca_once(builder, dbl)
        c = cgutils.alloca_once(builder, dbl)
        builder.call(fn, [args[0], s, c])
        return context.make_tuple(builder, signature.return_type, [builder.load(s), builder.load(c)])
    return sig, codegen
