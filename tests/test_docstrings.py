"""The docstrings the API reference validates (docs/conf.py, numpydoc_validation_checks), checked
here so that a missing parameter or return description fails the tests, not only the docs build
that runs after them."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re

import pytest

import bayesid

validate = pytest.importorskip("numpydoc.validate").validate

# the same checks and exclusions as docs/conf.py
CHECKS = {"PR01", "PR02", "PR03", "PR04", "PR07", "PR10", "RT01", "RT03"}
EXCLUDE = [re.compile(r"^bayesid\.models\.interface\.SimulationModel$")]


def _modules():
    yield bayesid
    for info in pkgutil.walk_packages(bayesid.__path__, "bayesid."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            yield importlib.import_module(info.name)


def _is_code(obj) -> bool:
    return inspect.isclass(obj) or inspect.isroutine(obj) or hasattr(obj, "py_func")


def _documented():
    """Dotted names of the functions, classes and methods autodoc documents (with a docstring)."""
    for mod in _modules():
        names = getattr(mod, "__all__", None) or [n for n in vars(mod) if not n.startswith("_")]
        for n in names:
            obj = getattr(mod, n, None)
            if not _is_code(obj) or getattr(obj, "__module__", None) != mod.__name__:
                continue
            yield f"{mod.__name__}.{n}"
            if inspect.isclass(obj):
                for m, member in vars(obj).items():
                    if m.startswith("_") or isinstance(member, property):
                        continue
                    func = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
                    if inspect.isroutine(func) and func.__doc__:
                        yield f"{mod.__name__}.{n}.{m}"


def test_every_documented_object_passes_the_docs_builds_numpydoc_checks():
    problems = []
    for name in sorted(set(_documented())):
        if any(p.match(name) for p in EXCLUDE):
            continue
        errors = [f"{code} {msg}" for code, msg in validate(name)["errors"] if code in CHECKS]
        if errors:
            problems.append(f"{name}: {'; '.join(errors)}")
    assert not problems, "docstrings the docs build (-W) would refuse:\n" + "\n".join(problems)
