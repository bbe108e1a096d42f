"""The layout shows the data flow (issue 22): each layer imports only the layers before it, no
module reaches into another's private names, and the package docstring and the README's map name
every module."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "bayesid"
#: layers in data-flow order (the task layer under all); a module may import its own layer and the ones before it
LAYERS = ["tasks", "data", "protocol", "models", "estimation", "analysis", "report", "cases", "cli"]


def _modules():
    for f in sorted(PKG.rglob("*.py")):
        parts = list(f.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        yield f, parts


def _layer(parts) -> int | None:
    return LAYERS.index(parts[1]) if len(parts) > 1 and parts[1] in LAYERS else None


def _imports(f, parts):
    """(imported module parts, names) of every import in a package file, relative ones resolved."""
    pkg = parts if f.name == "__init__.py" else parts[:-1]
    for node in ast.walk(ast.parse(f.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - (node.level - 1)]
                mod = base + (node.module.split(".") if node.module else [])
            else:
                mod = node.module.split(".") if node.module else []
            if mod[:1] == ["bayesid"]:
                yield mod, [a.name for a in node.names], node.lineno
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("bayesid"):
                    yield a.name.split("."), [], node.lineno


def test_each_layer_imports_only_the_layers_before_it():
    bad = []
    for f, parts in _modules():
        own = _layer(parts)
        if own is None:
            continue
        for mod, names, line in _imports(f, parts):
            targets = [mod + [n] if len(mod) == 1 else mod for n in (names or [None])] if len(mod) == 1 else [mod]
            for t in targets:
                lay = _layer([x for x in t if x is not None])
                if lay is not None and lay > own:
                    bad.append(f"{f.relative_to(ROOT)}:{line} imports {'.'.join(x for x in t if x)}")
    assert not bad, "\n".join(bad)


def test_no_module_imports_another_modules_private_name():
    bad = [
        f"{f.relative_to(ROOT)}:{line}: {'.'.join(mod)} {n}"
        for f, parts in _modules()
        for mod, names, line in _imports(f, parts)
        for n in names
        if n.startswith("_") and not n.startswith("__")
    ]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("where", ["package docstring", "README map"])
def test_every_module_is_named(where):
    text = (PKG / "__init__.py").read_text() if where == "package docstring" else (ROOT / "README.md").read_text()
    missing = []
    for f, parts in _modules():
        if len(parts) == 1 or parts[1] == "analysis" and len(parts) > 3:  # the gap package names its parts
            continue
        key = ".".join(parts) if where == "package docstring" else f.name
        if f.name == "__init__.py" and where == "README map":
            key = parts[-1] + "/"
        if key not in text:
            missing.append(".".join(parts))
    assert not missing, f"not named in the {where}: {missing}"
