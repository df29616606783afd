"""The house rules of docs/ARCHITECTURE.md, checked on the source: the layers import only downwards, no
import cycle (imports inside functions included), no platform tricks in the package."""
from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

from conftest import ROOT

PKG = ROOT / "frictid"

#: Rank of each top-level part of the package: a module may import only from ranks at or below its own.
LAYERS = {
    # 0: numbers and the objects that hold them
    "errors": 0, "data": 0, "version": 0, "models": 0, "model": 0, "result": 0, "parallel": 0,
    # 1: numerics on arrays (simulation, segments, identification, diagnosis, replay, comparison)
    "plant": 1, "segments": 1, "identify": 1, "diagnose": 1, "replay": 1, "compare": 1,
    # 2: files in and out, the report, the library's entry points that read files
    "io": 2, "report": 2, "api": 2,
    # 3: the command line and the package's public surface
    "cli": 3, "__main__": 3, "__init__": 3,
    "fleet": 2, "export": 2, "compensate": 1, "robot": 1, "robotfit": 2,
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """Every frictid module that ``name`` imports, at module level or inside functions."""
    out = set()
    is_pkg = path.name == "__init__.py"
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name in known)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_pkg else name.split(".")[:-1]
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            subs = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in known]
            if subs:
                out.update(subs)
            if target in known and len(subs) < len(node.names):
                out.add(target)
    out.discard(name)
    return out


def part(mod: str) -> str:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    mods = modules()
    return {m: imports_of(m, p, set(mods)) for m, p in mods.items()}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one node (Tarjan), each sorted."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
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

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_every_part_has_a_layer(graph):
    assert not sorted({part(m) for m in graph} - set(LAYERS))


def test_no_import_cycle_between_modules(graph):
    assert cycles(graph) == []


def test_no_import_cycle_between_parts(graph):
    parts = defaultdict(set)
    for m, targets in graph.items():
        parts[part(m)].update(part(t) for t in targets if part(t) != part(m))
    assert cycles(parts) == []


def test_layers_import_only_downwards(graph):
    bad = sorted(f"{m} -> {t}" for m, targets in graph.items() for t in targets
                 if LAYERS[part(t)] > LAYERS[part(m)])
    assert bad == []


def test_no_platform_tricks_in_the_package():
    words = ("ctypes", "gc.freeze", "mallopt", "malloc_trim", "madvise", "ARROW_DEFAULT_MEMORY_POOL", "prctl")
    found = [f"{p.relative_to(ROOT)}:{k}: {w}" for p in PKG.rglob("*.py")
             for k, line in enumerate(p.read_text().splitlines(), 1) for w in words if w in line]
    assert found == []
