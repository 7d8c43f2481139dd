"""The architecture of docs/architecture.md, held by a test: which room may import which, no import cycles, no
private names reached across modules, no function longer than 80 lines outside tests and benchmarks.

Imports are read from the source text (ast), at any depth (function-level imports count too), so the rules hold for
what the code can reach, not only for what it imports at load time.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("firmware_model", "can_dbc", "tools")
MAX_FUNCTION_LINES = 80

#: room -> rooms it must never import (prefix match on dotted module names)
FORBIDDEN = {
    "can_dbc": ("firmware_model", "tools"),
    "firmware_model": ("tools",),
    "firmware_model.physics": (
        "firmware_model.onboard",
        "firmware_model.service",
        "firmware_model.network",
        "firmware_model.config",
    ),
    "firmware_model.onboard": ("firmware_model.service", "can_dbc"),
    "firmware_model.units": ("firmware_model.", "can_dbc", "tools"),
    "firmware_model.components": ("firmware_model.", "can_dbc", "tools"),
    "firmware_model.errors": ("firmware_model.", "can_dbc", "tools"),
    # measured SCADA records have no CAN side
    "tools.scada": ("can_dbc", "firmware_model.service"),
}
#: nothing but the console entry point imports the CLI modules
CLI = "tools.cli"


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for f in (ROOT / pkg).rglob("*.py"):
            rel = f.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join(parts)] = f
    return mods


MODULES = _modules()
TREES = {name: ast.parse(path.read_text(), filename=str(path)) for name, path in MODULES.items()}


def _imports(name: str, tree: ast.AST) -> list[tuple[str, list[str], int]]:
    """(imported module, names imported from it, line) for every import in the module, at any depth."""
    out = []
    pkg = name if MODULES[name].name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.extend((a.name, [], node.lineno) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if node.level:
                base = pkg.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([mod] if mod else []))
            names = [a.name for a in node.names]
            # "from pkg import module" imports a module
            subs = [f"{mod}.{n}" for n in names if f"{mod}.{n}" in MODULES]
            out.append((mod, [n for n in names if f"{mod}.{n}" not in MODULES], node.lineno))
            out.extend((s, [], node.lineno) for s in subs)
    return [o for o in out if o[0].split(".")[0] in PACKAGES]


IMPORTS = {name: _imports(name, tree) for name, tree in TREES.items()}


def _room_rules(name: str):
    for room, banned in FORBIDDEN.items():
        if name == room or name.startswith(room + "."):
            yield room, banned


def test_rooms_import_only_what_they_may():
    bad = []
    for name, imps in IMPORTS.items():
        for room, banned in _room_rules(name):
            for mod, _, line in imps:
                for b in banned:
                    if (
                        mod == b.rstrip(".") or mod.startswith(b if b.endswith(".") else b + ".") or mod == b
                    ) and not mod.startswith(room):
                        bad.append(f"{name}:{line} imports {mod} ({room} may not import {b})")
    assert not bad, "\n".join(bad)


def test_only_the_cli_imports_the_cli():
    bad = [
        f"{name}:{line} imports {mod}"
        for name, imps in IMPORTS.items()
        if not name.startswith(CLI)
        for mod, _, line in imps
        if mod == CLI or mod.startswith(CLI + ".")
    ]
    assert not bad, "libraries must not import the CLI modules:\n" + "\n".join(bad)


def _graph(top_level_only: bool) -> dict[str, set]:
    g = {}
    for name, tree in TREES.items():
        body = tree.body if top_level_only else None
        imps = _imports(name, ast.Module(body=body, type_ignores=[])) if top_level_only else IMPORTS[name]
        g[name] = {m for m, _, _ in imps if m in MODULES and m != name}
    return g


def _cycles(g: dict[str, set]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in list(g):
        if v not in index:
            visit(v)
    return out


def _package_of(mod: str) -> str:
    """A package's __init__ belongs to the package; imports of it from its own modules are not cycles."""
    return mod


def test_no_import_cycles():
    g = _graph(top_level_only=False)
    # a package __init__ that only holds a docstring is no dependency; drop edges into __init__ modules of packages
    inits = {m for m, p in MODULES.items() if p.name == "__init__.py" and len(TREES[m].body) <= 1}
    g = {k: {m for m in v if m not in inits} for k, v in g.items()}
    assert not _cycles(g), f"import cycles: {_cycles(g)}"


def test_no_private_names_across_modules():
    bad = []
    for name, imps in IMPORTS.items():
        for mod, names, line in imps:
            for n in names:
                if n.startswith("_") and not n.startswith("__") and mod != name:
                    bad.append(f"{name}:{line} imports {mod}.{n}")
    for name, tree in TREES.items():
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                for a in node.names:
                    if f"{node.module}.{a.name}" in MODULES:
                        aliases[a.asname or a.name] = f"{node.module}.{a.name}"
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name in MODULES and a.asname:
                        aliases[a.asname] = a.name
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Name)
                and node.value.id in aliases
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
            ):
                bad.append(f"{name}:{node.lineno} uses {aliases[node.value.id]}.{node.attr}")
    assert not bad, "private names used across modules:\n" + "\n".join(bad)


def test_no_function_over_80_lines():
    long = []
    for name, tree in TREES.items():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{name}.{node.name}: {n} lines")
    assert not long, "functions over 80 lines:\n" + "\n".join(long)


@pytest.mark.parametrize("room", sorted(FORBIDDEN))
def test_rooms_exist(room):
    """A rule about a room that no longer exists would pass in silence: every room named here exists."""
    assert any(m == room or m.startswith(room + ".") for m in MODULES), room
