"""The code's shape, as the structure review asks it: modules and functions small enough to
read, and kinds that answer for themselves (no caller compares a leader kind or a drive by
its name: it asks the kind's object)."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = sorted(p for folder in ("boids_env", "policies", "eval", "train", "bench",
                                  "docs/hooks")
                 for p in (ROOT / folder).rglob("*.py"))
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80
KIND_NAMES = {"robot", "person", "trajectory", "holonomic", "unicycle"}
"""The built-in leader kinds' and drives' names."""
KIND_FIELDS = {"leader", "drive"}
OWNERS = {ROOT / "boids_env/world/leader_kinds.py", ROOT / "boids_env/world/robots.py"}
"""The modules that own the kinds (they name them)."""


def _rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


def test_no_module_is_over_600_lines():
    long = {_rel(p): n for p in SOURCES
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, long


def test_no_function_is_over_80_lines():
    long = {}
    for path in SOURCES:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long[f"{_rel(path)}:{node.lineno} {node.name}"] = lines
    assert not long, long


def _names_a_kind_field(node: ast.AST) -> bool:
    """``x.leader``, ``drive``, ``fields.get("leader")``, ``fields["drive"]``."""
    if isinstance(node, ast.Attribute):
        return node.attr in KIND_FIELDS
    if isinstance(node, ast.Name):
        return node.id in KIND_FIELDS
    if isinstance(node, ast.Call) and node.args:
        first = node.args[0]
        return isinstance(first, ast.Constant) and first.value in KIND_FIELDS
    if isinstance(node, ast.Subscript):
        key = node.slice
        return isinstance(key, ast.Constant) and key.value in KIND_FIELDS
    return False


def _kind_names(node: ast.AST) -> bool:
    if isinstance(node, ast.Constant):
        return node.value in KIND_NAMES
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        return any(_kind_names(e) for e in node.elts)
    return False


def kind_comparisons(tree: ast.AST) -> list[int]:
    """Lines that compare a leader kind's or a drive's field with a kind's name."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(_names_a_kind_field(s) for s in sides) and any(_kind_names(s)
                                                                  for s in sides):
                found.append(node.lineno)
    return found


def test_the_check_finds_what_it_looks_for():
    tree = ast.parse('a = sc.leader == "robot"\nb = w.drive != "unicycle"\n'
                     'c = f.get("leader") in ("person", "x")\nd = obs.action == "unicycle"\n'
                     'e = sc.leader_kind.walks(sc)\n')
    assert kind_comparisons(tree) == [1, 2, 3]


@pytest.mark.parametrize("path", [p for p in SOURCES if p not in OWNERS], ids=_rel)
def test_no_caller_compares_a_kind_by_name(path):
    lines = kind_comparisons(ast.parse(path.read_text()))
    assert not lines, f"{_rel(path)} compares a leader kind or a drive by name at lines " \
                      f"{lines}: ask scenario.leader_kind / world.drive_model instead"
