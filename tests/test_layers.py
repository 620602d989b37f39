"""The four layers import downwards only: models < data < identification < benchmarks."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RANK = {"models": 0, "data": 1, "identification": 2, "benchmarks": 3}


def imported_modules(tree: ast.AST, package: str):
    """(line, absolute module name, inside a function) for every import of a hysbench module."""
    parents = {}
    for node in ast.walk(tree):
        for child in ast.iter_child_nodes(node):
            parents[child] = node

    def in_function(node):
        while node in parents:
            node = parents[node]
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                return True
        return False

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the module's package
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                names = [".".join(base + ([node.module] if node.module else []))]
            else:
                names = [node.module or ""]
        else:
            continue
        for name in names:
            if name.startswith("hysbench."):
                yield node.lineno, name, in_function(node)


def python_files():
    for top in RANK:
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT)
            if rel.parts[:2] == ("benchmarks", "speed"):
                continue  # pytest-benchmark files, not part of the package
            yield top, path


def module_package(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = ["hysbench", *rel.parts]
    return ".".join(parts if path.name == "__init__.py" else parts[:-1])


def test_the_walk_sees_every_layer():
    seen = {top for top, _ in python_files()}
    assert seen == set(RANK)


def test_a_planted_upward_import_is_caught():
    tree = ast.parse("def f():\n    from hysbench.benchmarks import cli\n")
    found = list(imported_modules(tree, "hysbench.models"))
    assert found == [(2, "hysbench.benchmarks", True)]


@pytest.mark.parametrize("top", list(RANK))
def test_imports_point_down_only(top):
    upward = []
    for layer, path in python_files():
        if layer != top:
            continue
        for line, name, _ in imported_modules(ast.parse(path.read_text()), module_package(path)):
            target = name.split(".")[1]
            if RANK.get(target, -1) > RANK[layer]:
                upward.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert not upward, "imports pointing up a layer:\n" + "\n".join(upward)


def test_no_hysbench_import_inside_a_function():
    """Imports inside functions are how a cycle hides; every hysbench import is at module level."""
    hidden = []
    for _, path in python_files():
        for line, name, in_function in imported_modules(ast.parse(path.read_text()), module_package(path)):
            if in_function:
                hidden.append(f"{path.relative_to(ROOT)}:{line} imports {name} inside a function")
    assert not hidden, "\n".join(hidden)
