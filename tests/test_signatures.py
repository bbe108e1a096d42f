"""No public function or method of the package takes more than 8 parameters (STYLE.md: past about
eight a function wants an options object), except the drivers whose arguments are those of a
compiled kernel: the kernels take flat arrays, and their Python twins mirror them."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import bayesid

MOST = 8
#: kernel drivers: the argument lists of the numba kernels they run or stand in for
KERNEL_INTERFACES = {
    "bayesid.models.codegen.Interpreted.simulate_batch",
    "bayesid.models.codegen.Interpreted.simulate_windows",
    "bayesid.models.codegen.Open.simulate_batch",
    "bayesid.models.codegen.Open.simulate_windows",
    "bayesid.models.ship.kernel.simulate_windows",
}


def _public_functions():
    """(qualified name, function) of every public function and method the package defines."""
    for info in pkgutil.walk_packages(bayesid.__path__, "bayesid."):
        if info.name.endswith("__main__"):
            continue
        mod = importlib.import_module(info.name)
        for name, obj in vars(mod).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != mod.__name__:
                continue
            if hasattr(obj, "py_func"):  # a numba dispatcher: a kernel
                continue
            if inspect.isfunction(obj):
                yield f"{mod.__name__}.{name}", obj
            elif inspect.isclass(obj):
                for attr, member in vars(obj).items():
                    member = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
                    if not attr.startswith("_") and inspect.isfunction(member):
                        yield f"{mod.__name__}.{name}.{attr}", member


def test_no_public_function_takes_more_than_eight_parameters():
    long = {}
    for qual, fn in _public_functions():
        n = len([p for p in inspect.signature(fn).parameters if p not in ("self", "cls")])
        if n > MOST and qual not in KERNEL_INTERFACES:
            long[qual] = n
    assert not long, f"more than {MOST} parameters (group the secondary ones in an options object): {long}"
