"""No two modules of the library, the viewer or the benchmarks import each other, however indirectly.

An import circle works only in one order of first imports, and a lazy import inside a function hides
it until that function runs; what both sides need belongs in a leaf module both import. Every import
counts here: at the top, inside a function, under `if TYPE_CHECKING:`. Read from the source with
`ast`, so nothing is imported and the test takes a moment.
"""

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("ikdp", "ikdp_viz", "benchmarks")


def module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def project_modules() -> dict[str, Path]:
    return {module_name(path): path for package in PACKAGES for path in sorted((REPO / package).rglob("*.py"))}


def imported_names(path: Path, name: str) -> set[str]:
    """Every dotted name the file imports: `import a.b` gives a.b, `from a import b` a.b, relative imports resolved."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # from . import x, from ..y import z: against this module's package
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            # a.b when b is a module, else a (b is a name in it): import_graph keeps the deepest module
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


def import_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the project modules it imports. `import a.b.c` counts as an import of a.b.c, not of the
    packages a and a.b above it: a package importing its own submodules is how packages are made."""
    graph = {}
    for name, path in modules.items():
        targets = set()
        for imported in imported_names(path, name):
            parts = imported.split(".")
            deepest = next(
                (".".join(parts[:size]) for size in range(len(parts), 0, -1) if ".".join(parts[:size]) in modules),
                None,
            )
            if deepest is not None and deepest != name:
                targets.add(deepest)
        graph[name] = targets
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One circle of each strongly connected group of modules (Tarjan's algorithm), as a path back to its start."""
    index, low, on_stack, stack, groups = {}, {}, set(), [], []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph[node]):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            group = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.add(member)
                if member == node:
                    break
            if len(group) > 1:
                groups.append(group)

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return [circle_in(graph, group) for group in groups]


def circle_in(graph: dict[str, set[str]], group: set[str]) -> list[str]:
    """A shortest path from the group's first module back to itself, inside the group (breadth first)."""
    start = min(group)
    previous = {start: None}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for successor in sorted(graph[node] & group):
                if successor == start:
                    path = [node]
                    while previous[path[-1]] is not None:
                        path.append(previous[path[-1]])
                    return [start, *reversed(path[:-1]), start] if len(path) > 1 else [start, node, start]
                if successor not in previous:
                    previous[successor] = node
                    following.append(successor)
        frontier = following
    raise AssertionError(f"no circle in the group {sorted(group)}")


def test_no_module_imports_itself_back():
    found = circles(import_graph(project_modules()))
    assert not found, "import circles: " + "; ".join(" -> ".join(circle) for circle in found)


def test_the_graph_sees_lazy_relative_and_type_checking_imports(tmp_path):
    """The reader finds a circle however it is hidden: a test of the test, on a small made-up package."""
    package = tmp_path / "shapes"
    package.mkdir()
    (package / "__init__.py").write_text("from shapes.square import Square\n")
    (package / "square.py").write_text("def area():\n    from .units import metre\n    return metre\n")
    (package / "units.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from shapes import square\n"
    )
    (package / "leaf.py").write_text("import shapes.units\n")
    modules = {
        ".".join(path.relative_to(tmp_path).with_suffix("").parts).removesuffix(".__init__"): path
        for path in package.rglob("*.py")
    }
    graph = import_graph(modules)
    assert graph == {
        "shapes": {"shapes.square"},
        "shapes.square": {"shapes.units"},
        "shapes.units": {"shapes.square"},
        "shapes.leaf": {"shapes.units"},
    }
    assert circles(graph) == [["shapes.square", "shapes.units", "shapes.square"]]


@pytest.mark.parametrize(
    ("graph", "expected"),
    [
        ({"a": {"b"}, "b": {"c"}, "c": set()}, []),
        ({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}, [["a", "b", "c", "a"]]),
        ({"a": {"b", "c"}, "b": {"a"}, "c": {"d"}, "d": {"c"}}, [["c", "d", "c"], ["a", "b", "a"]]),
    ],
)
def test_circles_are_named_one_per_group(graph, expected):
    assert circles(graph) == expected
