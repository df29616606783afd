"""Functions a reader can hold: none in the segmentation, identification, diagnosis and report packages is
longer than :data:`MAX_LINES` (from its first decorator or ``def`` to its last line, docstring included)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

import frictid

MAX_LINES = 80
ROOT = Path(frictid.__file__).parent


def long_functions(package: str) -> list[str]:
    """``file:line name: n lines`` of every function (methods and nested functions included) of
    ``frictid/<package>/`` longer than :data:`MAX_LINES`."""
    out = []
    for path in sorted((ROOT / package).rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([node.lineno] + [d.lineno for d in node.decorator_list])
                n = node.end_lineno - first + 1
                if n > MAX_LINES:
                    out.append(f"{path.relative_to(ROOT.parent)}:{node.lineno} {node.name}: {n} lines")
    return out


@pytest.mark.parametrize("package", ["segments", "report", "identify", "diagnose"])
def test_no_function_is_longer_than_80_lines(package):
    long = long_functions(package)
    assert not long, f"{len(long)} functions over {MAX_LINES} lines in frictid/{package}/:\n" + "\n".join(long)
