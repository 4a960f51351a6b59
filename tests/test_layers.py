"""The package layers, read from the source (AST, imports inside functions included):
sim at the bottom, conform and viz on it (not on each other), garment on top; and no
module imports itself back through others (no cycles)."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.support.paths import ROOT
# Package -> the project's packages it may import (besides itself).
MAY_IMPORT = {"sim": set(), "conform": {"sim"}, "viz": {"sim"}, "garment": {"sim", "conform", "viz"}}


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, root: Path, modules: set[str]) -> list[tuple[str, int]]:
    """(imported project module, line) for every import in the file, at any depth.
    `from package import name` counts as the submodule when `name` is one."""
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                origin = ".".join(base + ([node.module] if node.module else []))
            else:
                origin = node.module
            targets = [f"{origin}.{a.name}" if f"{origin}.{a.name}" in modules else origin for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in modules:  # `import a.b.c` of a name inside a module
                t = t.rpartition(".")[0]
            if t:
                found.append((t, node.lineno))
    return found


def check(root: Path, may_import: dict[str, set[str]]) -> list[str]:
    """Every import against the layers, then every cycle; one line per problem."""
    files = {module_name(p, root): p for top in may_import for p in sorted((root / top).rglob("*.py"))}
    graph: dict[str, set[str]] = {m: set() for m in files}
    problems = []
    for mod, path in files.items():
        top = mod.split(".")[0]
        for target, line in imports(path, root, set(files)):
            other = target.split(".")[0]
            if other != top and other not in may_import[top]:
                problems.append(f"{path.relative_to(root)}:{line}: {top} imports {target} (a layer above or beside)")
            if target != mod:
                graph[mod].add(target)
    return problems + [f"import cycle: {' -> '.join(c)}" for c in cycles(graph)]


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), sorted."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
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

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(out)


def test_layers_point_down_and_nothing_imports_itself_back():
    problems = check(ROOT, MAY_IMPORT)
    assert not problems, "\n".join(problems)


def test_the_check_finds_an_upward_import_a_sideways_one_and_a_cycle(tmp_path):
    def write(rel, text):
        p = tmp_path / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)

    for top in MAY_IMPORT:
        write(f"{top}/__init__.py", "")
    write("sim/a.py", "def f():\n    from garment import app  # hidden in a function\n")
    write("garment/app.py", "import sim.a\n")
    write("conform/x.py", "from viz import y\n")
    write("viz/y.py", "")
    write("sim/b.py", "from . import c\n")
    write("sim/c.py", "from .b import thing\n")
    problems = check(tmp_path, MAY_IMPORT)
    assert any(p.startswith("sim/a.py:2: sim imports garment.app") for p in problems), problems
    assert any(p.startswith("conform/x.py:1: conform imports viz.y") for p in problems), problems
    assert "import cycle: sim.b -> sim.c" in problems
    assert "import cycle: garment.app -> sim.a" in problems
    assert len(problems) == 4, problems
