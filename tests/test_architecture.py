"""Rules of the house, checked on the source tree: no import cycles, no module over 400 lines, codecs
never import the API, the CLI or the container, and readers never import codecs."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
MAX_LINES = 400


def _modules() -> dict[str, Path]:
    out = {}
    for f in SRC.rglob("*.py"):
        parts = f.relative_to(SRC).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = f
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> mocapz modules it imports (anywhere in the file, function-level imports included).

    ``from package import submodule`` counts as importing the submodule only.
    """
    mods = _modules()
    graph: dict[str, set[str]] = {}
    for name, f in mods.items():
        deps: set[str] = set()
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("mocapz"):
                subs = [f"{node.module}.{a.name}" for a in node.names if f"{node.module}.{a.name}" in mods]
                deps.update(subs)
                if len(subs) < len(node.names):
                    deps.add(node.module)
            elif isinstance(node, ast.Import):
                deps.update(a.name for a in node.names if a.name.startswith("mocapz"))
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_no_import_cycles() -> None:
    assert cycles(import_graph()) == []


def test_cycle_finder_finds_a_cycle() -> None:
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_layers() -> None:
    graph = import_graph()
    for name, deps in graph.items():
        if name.startswith("mocapz.codecs"):
            bad = {d for d in deps if d.startswith(("mocapz.api", "mocapz.cli", "mocapz.format.container",
                                                     "mocapz.io", "mocapz.parallel", "mocapz.viewer"))}
            assert not bad, f"{name} (a codec) imports {sorted(bad)}"
        if name.startswith(("mocapz.io", "mocapz.model", "mocapz.format")):
            bad = {d for d in deps if d.startswith(("mocapz.codecs", "mocapz.api", "mocapz.cli"))}
            assert not bad, f"{name} imports {sorted(bad)}"


def test_no_module_over_400_lines() -> None:
    counts = {name: len(f.read_text(encoding="utf-8").splitlines()) for name, f in _modules().items()}
    long = {name: n for name, n in counts.items() if n > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"
