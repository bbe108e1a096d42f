"""Sphinx configuration of the bayesid documentation.

Build (warnings are errors; the examples run during the build):

    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from __future__ import annotations

import importlib
import inspect
import os
import pkgutil
import re
import sys
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS.parent))

from sphinx.pycode import ModuleAnalyzer  # noqa: E402

import bayesid  # noqa: E402

project = "bayesid"
author = "the bayesid developers"
copyright = "the bayesid developers"
version = release = bayesid.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "sphinxarg.ext",  # sphinx-argparse: the command reference (cli.rst) generated from the parsers
]

exclude_patterns = ["_build", "examples/README.rst"]
templates_path: list[str] = []

html_theme = "pydata_sphinx_theme"
html_title = f"bayesid {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 7,
}
# The user guide pages are single pages: no left sidebar; the API reference keeps it.
html_sidebars = {
    page: []
    for page in (
        "index",
        "getting_started",
        "install",
        "quickstart",
        "vessel",
        "reading_reports",
        "gap",
        "posterior",
        "performance",
        "formats",
        "faq",
        "architecture",
    )
}
html_static_path: list[str] = []

# ---- docstrings --------------------------------------------------------------------------------
# The package's docstrings are numpydoc, one entry per parameter. numpydoc validates the
# parameter and return sections of every documented object (a warning, hence an error under -W):
# PR01 a parameter not documented, PR02 a documented parameter the signature does not have,
# PR03 parameters in another order than the signature, PR04 a parameter without a type, PR07 a
# parameter without a description, PR10 no space before the colon of "name : type", RT01 a
# function that returns something without a Returns section, RT03 a return value without a
# description. No class-member tables (autodoc documents the members itself).
numpydoc_validation_checks = {"PR01", "PR02", "PR03", "PR04", "PR07", "PR10", "RT01", "RT03"}
numpydoc_validation_exclude = {
    # a typing.Protocol: its inherited __init__(*args, **kwargs) only refuses instantiation, so
    # there are no constructor parameters to document (its methods are validated)
    r"^bayesid\.models\.interface\.SimulationModel$",
}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
autodoc_default_options = {"members": True, "member-order": "bysource", "no-value": True}
autodoc_typehints = "none"
autodoc_preserve_defaults = True

# ---- API reference -----------------------------------------------------------------------------
# One page per public module, generated at each build from the package itself, so a new module
# shows up without editing the docs. A module documents the names it defines (its __all__ when
# it has one); names re-exported from a submodule are documented there.
API_EXCLUDE: set = set()  # modules left out of the API reference (none)


def _public_modules() -> list[str]:
    names = ["bayesid"]
    for info in pkgutil.walk_packages(bayesid.__path__, "bayesid."):
        name = info.name
        if any(part.startswith("_") for part in name.split(".")) or name in API_EXCLUDE:
            continue
        names.append(name)
    return sorted(names)


def _is_code(obj) -> bool:
    return inspect.isclass(obj) or inspect.isroutine(obj) or hasattr(obj, "py_func")  # numba dispatcher


def _documented_data(modname: str) -> set[str]:
    """Module-level names with a doc comment (``#:``) or docstring in the module's own source."""
    analyzer = ModuleAnalyzer.for_module(modname)
    return {name for (cls, name) in analyzer.find_attr_docs() if cls == ""}


def _members(mod) -> tuple[list[str], list[str]]:
    """(names documented on the module's page, other public names it defines or lists)."""
    listed = (
        list(mod.__all__)
        if hasattr(mod, "__all__")
        else [n for n, obj in vars(mod).items() if not n.startswith("_") and _is_code(obj)]
    )
    docs = _documented_data(mod.__name__)
    members, others = [], []
    for n in listed:
        obj = getattr(mod, n)
        if inspect.ismodule(obj):
            continue
        if _is_code(obj):
            if getattr(obj, "__module__", None) == mod.__name__:
                members.append(n)
            elif hasattr(mod, "__all__"):  # a re-export the module lists (otherwise an import)
                others.append(n)
        else:
            (members if n in docs else others).append(n)
    return members, others


def _write_api_pages(app) -> None:
    out = DOCS / "api" / "generated"
    out.mkdir(parents=True, exist_ok=True)
    modules = _public_modules()
    pages = {}
    for name in modules:
        mod = importlib.import_module(name)
        members, others = _members(mod)
        lines = [name, "=" * len(name), "", f".. automodule:: {name}", "   :no-members:", ""]
        if others:
            lines += [
                "Other public names here: "
                + ", ".join(f"``{n}``" for n in others)
                + " (imported from the module that defines them, or constants without a doc comment).",
                "",
            ]
        for m in members:
            lines += [_directive(mod, name, m), ""]
        pages[f"{name}.rst"] = "\n".join(lines)
    index = ["Modules", "=======", "", ".. toctree::", "   :maxdepth: 1", ""]
    index += [f"   {name}" for name in modules]
    pages["modules.rst"] = "\n".join(index) + "\n"
    for fname, text in pages.items():
        path = out / fname
        if not path.exists() or path.read_text() != text:  # keep mtimes for incremental builds
            path.write_text(text)
    for stale in out.glob("*.rst"):
        if stale.name not in pages:
            stale.unlink()


def _directive(mod, modname: str, name: str) -> str:
    obj = getattr(mod, name)
    if inspect.isclass(obj):
        kind = "exception" if issubclass(obj, BaseException) else "class"
        return f".. auto{kind}:: {modname}.{name}\n   :members:"
    if inspect.isroutine(obj) or hasattr(obj, "py_func"):
        return f".. autofunction:: {modname}.{name}"
    return f".. autodata:: {modname}.{name}\n   :no-value:"


# The docstrings write absolute values as |v| (``v|v|``, ``|r| <= 0.1``); in reStructuredText
# that is a substitution reference. Outside inline literals and roles, such bars are escaped so
# they print as written.
_LITERAL = re.compile(r"(``.+?``|:\w+:`[^`]*`|`[^`]*`_{0,2})")
_ABS = re.compile(r"(?<![\\|])\|(\S(?:[^|`]*?\S)?)\|(?!_)")


def _absolute_values(app, what, name, obj, options, lines) -> None:
    for i, line in enumerate(lines):
        if "|" in line:
            parts = _LITERAL.split(line)
            lines[i] = "".join(p if k % 2 else _ABS.sub(r"\\|\1\\|", p) for k, p in enumerate(parts))


def setup(app):
    app.connect("builder-inited", _write_api_pages)
    app.connect("autodoc-process-docstring", _absolute_values, priority=600)  # after numpydoc


# ---- examples ----------------------------------------------------------------------------------
# Executed at every build; a failing example fails the build.
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "min_reported_time": 0,
    "matplotlib_animations": False,
    "reset_modules": ("matplotlib",),
}
