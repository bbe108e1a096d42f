"""The layout shows the data flow: each layer imports only the layers before it, no modules import
each other in a circle (function-level imports included), no module reaches into another's private
names, and the package docstring and the map of docs/architecture.rst name every module."""

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


#: structure discovery's modules by concept, each importing only those before it (the package, the
#: orchestration, last)
DISCOVERY = ["options", "library", "forces", "selection", "confirmation", "__init__"]


def test_structure_discovery_modules_import_only_the_concepts_before_them():
    pkg = ["bayesid", "analysis", "gap", "discovery"]
    found, bad = set(), []
    for f, parts in _modules():
        if parts[:4] != pkg:
            continue
        me = f.stem
        found.add(me)
        assert me in DISCOVERY, f"{f.relative_to(ROOT)}: a new module of structure discovery, place it in DISCOVERY"
        for mod, names, line in _imports(f, parts):
            if mod[:4] != pkg:
                continue
            used = mod[4:5] or [n for n in names if n in DISCOVERY] or ["__init__"]
            if any(DISCOVERY.index(u) >= DISCOVERY.index(me) for u in used):
                bad.append(f"{f.relative_to(ROOT)}:{line} imports {'.'.join(mod)} {names}")
    assert found == set(DISCOVERY)
    assert not bad, "\n".join(bad)


def import_graph(modules) -> dict:
    """{module: set of package modules it imports} of ``[(path, parts)]``: ``from pkg import name``
    counts as an import of ``pkg.name`` when that is a module, else of ``pkg``."""
    modules = list(modules)
    names = {".".join(parts) for _, parts in modules}
    edges = {}
    for f, parts in modules:
        me = ".".join(parts)
        edges[me] = set()
        for mod, imported, _ in _imports(f, parts):
            target = ".".join(mod)
            subs = {f"{target}.{n}" for n in imported if f"{target}.{n}" in names}
            if len(subs) < max(len(imported), 1) and target in names:
                subs.add(target)
            edges[me] |= subs - {me}
    return edges


def circles(edges: dict) -> list:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while not comp or comp[-1] != v:
                comp.append(stack.pop())
                on.discard(comp[-1])
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_no_modules_import_each_other_in_a_circle():
    found = circles(import_graph(_modules()))
    assert not found, found


@pytest.mark.parametrize(
    "edges, expect",
    [
        ({"a": {"b"}, "b": {"a"}, "c": set()}, [["a", "b"]]),
        ({"a": {"b"}, "b": {"c"}, "c": set()}, []),
        ({"a": {"b"}, "b": {"c"}, "c": {"a"}}, [["a", "b", "c"]]),
    ],
)
def test_the_circle_finder_finds_circles(edges, expect):
    assert circles(edges) == expect


def test_the_import_graph_reads_relative_and_deferred_imports(tmp_path):
    pkg = tmp_path / "bayesid"
    (pkg / "models").mkdir(parents=True)
    files = {
        pkg / "models" / "a.py": "def f():\n    from ..report import x\n",
        pkg / "report.py": "from .models import a\n",
    }
    for f, text in files.items():
        f.write_text(text)
    mods = [(f, list(f.relative_to(tmp_path).with_suffix("").parts)) for f in files]
    edges = import_graph(mods)
    assert edges == {"bayesid.models.a": {"bayesid.report"}, "bayesid.report": {"bayesid.models.a"}}
    assert circles(edges) == [["bayesid.models.a", "bayesid.report"]]


def test_no_module_imports_another_modules_private_name():
    bad = [
        f"{f.relative_to(ROOT)}:{line}: {'.'.join(mod)} {n}"
        for f, parts in _modules()
        for mod, names, line in _imports(f, parts)
        for n in names
        if n.startswith("_") and not n.startswith("__")
    ]
    assert not bad, "\n".join(bad)


def test_the_analysis_layer_never_asks_which_kind_of_vessel():
    """The layers above the models work with the model: no import of a family's package (its term
    library, kernels, file format) and no isinstance check against a family's vehicle type."""
    bad = []
    for f, parts in _modules():
        if len(parts) < 2 or parts[1] != "analysis":
            continue
        for mod, names, line in _imports(f, parts):
            if mod[:3] == ["bayesid", "models", "ship"] or (mod == ["bayesid", "models"] and "ship" in names):
                bad.append(f"{f.relative_to(ROOT)}:{line} imports {'.'.join(mod)}")
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "isinstance":
                kinds = ast.unparse(node.args[1]) if len(node.args) > 1 else ""
                if any(k in kinds for k in ("Ship", "Vehicle")):
                    bad.append(f"{f.relative_to(ROOT)}:{node.lineno} isinstance(..., {kinds})")
    assert not bad, "\n".join(bad)


def architecture_map() -> str:
    """The package map of ``docs/architecture.rst``: the text of its "The map" section."""
    text = (ROOT / "docs" / "architecture.rst").read_text()
    start = text.index("\nThe map\n-------\n")
    end = text.index("\n-----", start + len("\nThe map\n-------\n"))
    return text[start:end]


@pytest.mark.parametrize("where", ["package docstring", "architecture map"])
def test_every_module_is_named(where):
    text = (PKG / "__init__.py").read_text() if where == "package docstring" else architecture_map()
    missing = []
    for f, parts in _modules():
        if len(parts) == 1 or parts[1] == "analysis" and len(parts) > 3:  # the gap package names its parts
            continue
        key = ".".join(parts) if where == "package docstring" else f.name
        if f.name == "__init__.py" and where == "architecture map":
            key = parts[-1] + "/"
        if key not in text:
            missing.append(".".join(parts))
    assert not missing, f"not named in the {where}: {missing}"
