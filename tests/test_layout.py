"""The package's shape: one import name, layers that only import downwards, no import circles.

Every import statement of every module counts, those inside functions and ``TYPE_CHECKING``
blocks included."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"boids_env": "boids_env", "policies": "boids_env.policies", "eval": "boids_env.eval",
           "train": "boids_env.train", "bench": "boids_env.bench"}
LAYER = {"boids_env": 0, "boids_env.policies": 1, "boids_env.eval": 2, "boids_env.train": 3,
         "boids_env.bench": 4}
"""train -> eval -> policies -> boids_env (core); bench measures all of them."""


def _modules() -> dict[str, Path]:
    out = {}
    for folder, package in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join((package, *parts))] = path
    return out


def _imports(name: str, path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            found.append(base)
            found += [f"{base}.{alias.name}" for alias in node.names]
    return found


def _layer(module: str) -> int | None:
    best = None
    for package, layer in LAYER.items():
        if module == package or module.startswith(package + "."):
            if best is None or len(package) > len(best[0]):
                best = (package, layer)
    return None if best is None else best[1]


MODULES = _modules()


def test_every_module_is_under_the_one_import_name():
    generic = {"policies", "eval", "train", "bench"}
    for name, path in MODULES.items():
        for target in _imports(name, path):
            assert target.split(".")[0] not in generic, f"{path}: imports {target}"
    for path in (ROOT / "tests").rglob("*.py"):
        for target in _imports("tests", path):
            assert target.split(".")[0] not in generic, f"{path}: imports {target}"


@pytest.mark.parametrize("name", sorted(MODULES))
def test_no_layer_imports_one_above_it(name):
    own = _layer(name)
    for target in _imports(name, MODULES[name]):
        other = _layer(target)
        assert other is None or other <= own, f"{name} (layer {own}) imports {target} " \
                                              f"(layer {other})"


def test_no_import_circles():
    graph = {name: set() for name in MODULES}
    for name, path in MODULES.items():
        for target in _imports(name, path):
            while target and target not in MODULES:
                target = target.rpartition(".")[0]
            if target and target != name and not name.startswith(target + "."):
                graph[name].add(target)
    # packages import their own modules in __init__; a module importing its package's
    # __init__ is not a circle of ours
    done: set[str] = set()

    def visit(node: str, stack: list[str]) -> None:
        if node in stack:
            cycle = [*stack[stack.index(node):], node]
            raise AssertionError(f"import circle: {' -> '.join(cycle)}")
        if node in done:
            return
        for nxt in sorted(graph[node]):
            if nxt in LAYER and node.startswith(nxt + "."):
                continue
            visit(nxt, [*stack, node])
        done.add(node)

    for node in sorted(graph):
        visit(node, [])


def test_the_command_lives_in_the_top_layer():
    text = (ROOT / "pyproject.toml").read_text()
    assert 'boids = "boids_env.train.cli:main"' in text
    assert not (ROOT / "boids_env" / "cli.py").exists()
