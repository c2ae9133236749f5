"""The package's import graph has no cycles.

The graph is read from the source with ``ast`` (nothing is imported): one node per module of
bev_mdo, one edge per ``import``/``from ... import`` that names a bev_mdo module, whether it
stands at module level or inside a function (a function-level import is the usual way to hide
a cycle, so both count; ``if TYPE_CHECKING:`` blocks do not, they never run). ``from pkg import
name`` is an edge to ``pkg.name`` when that is a module, else to ``pkg``. Imports by computed
name (``importlib.import_module(f"...")``) are not seen.

ALLOWED lists the edges of the cycles that remain in modules other work is changing; the test
fails for any cycle that is not broken by removing them, and for an allowed edge that no longer
exists (so the list only shrinks).
"""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "bev_mdo"

# (importer, imported, "module" | "function"): edges that close the cycles still to be removed.
ALLOWED: set[tuple[str, str, str]] = set()  # none left; add an edge here only with a reason


def module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST):
    """(import node, 'module' | 'function') for every import that runs, skipping TYPE_CHECKING blocks."""
    def walk(node, level):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for sub in child.orelse:
                    yield from walk(ast.Module(body=[sub], type_ignores=[]), level)
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                yield child, level
            inner = "function" if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)) else level
            yield from walk(child, inner)
    yield from walk(tree, "module")


def import_graph() -> dict[tuple[str, str], set[str]]:
    """{(importer, imported): {'module', 'function'}} over the bev_mdo modules."""
    mods = modules()
    edges: dict[tuple[str, str], set[str]] = {}
    for name, path in mods.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node, level in _imports(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = node.module or ""
                if node.level:
                    up = package.split(".")
                    up = up[:len(up) - (node.level - 1)]
                    base = ".".join(up + ([base] if base else []))
                for a in node.names:
                    sub = f"{base}.{a.name}"
                    targets.append(sub if sub in mods else base)
            for t in targets:
                if t in mods and t != name:
                    edges.setdefault((name, t), set()).add(level)
    return edges


def cycles(edges) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    graph: dict[str, set[str]] = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
        graph.setdefault(b, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
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


def _without_allowed(edges):
    out = {}
    for (a, b), levels in edges.items():
        left = {lv for lv in levels if (a, b, lv) not in ALLOWED}
        if left:
            out[(a, b)] = left
    return out


def test_the_graph_is_read():
    edges = import_graph()
    # known edges of both kinds, so the reader cannot silently see nothing
    assert "module" in edges[("bev_mdo.models.chain", "bev_mdo.models.road_load")]
    assert "module" in edges[("bev_mdo.models.topology", "bev_mdo.models.quasi_static")]
    assert "function" in edges[("bev_mdo.models.fleet", "bev_mdo.models.chain")]


def test_the_cycle_finder_finds_cycles():
    assert cycles({("a", "b"): {"module"}, ("b", "c"): {"function"}, ("c", "a"): {"module"},
                   ("c", "d"): {"module"}}) == [["a", "b", "c"]]
    assert cycles({("a", "b"): {"module"}, ("b", "c"): {"module"}}) == []


def test_models_have_no_import_cycle():
    edges = {e: lv for e, lv in import_graph().items() if e[0].startswith("bev_mdo.models")
             and e[1].startswith("bev_mdo.models")}
    assert cycles(edges) == []


def test_no_import_cycle_in_the_package_but_the_allowed_ones():
    assert cycles(_without_allowed(import_graph())) == []


def test_every_allowed_edge_still_exists():
    edges = import_graph()
    gone = sorted(e for e in ALLOWED if e[2] not in edges.get((e[0], e[1]), set()))
    assert gone == [], f"remove these from ALLOWED, the import is gone: {gone}"


def _documented_layers() -> dict[str, int]:
    doc = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    block = doc.split("<!-- models-layers:begin -->")[1].split("<!-- models-layers:end -->")[0]
    layers = {}
    for line in block.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 2 and cells[0].isdigit():
            for name in cells[1].replace("`", " ").split():
                layers[f"bev_mdo.models.{name}"] = int(cells[0])
    return layers


def test_the_models_layers_match_the_imports():
    layers = _documented_layers()
    models = {m for m in modules() if m.startswith("bev_mdo.models.")}
    assert set(layers) == models, f"documented but missing: {set(layers) - models}; " \
                                  f"not documented: {models - set(layers)}"
    upward = sorted((a, b) for a, b in import_graph() if a in layers and b in layers and layers[b] >= layers[a])
    assert upward == [], f"imports from the same or a higher layer than docs/architecture.md says: {upward}"
    # every layer but the ground floor uses the one below it (the table is not padded with empty floors)
    used = {layers[b] for a, b in import_graph() if a in layers and b in layers}
    assert used >= set(range(max(layers.values())))


def _package_layers() -> tuple[dict[str, int], set[tuple[str, str]]]:
    """({package or top-level module: layer}, {(importer, imported) upward imports allowed}) from the
    package-layers block of docs/architecture.md."""
    doc = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    block = doc.split("<!-- package-layers:begin -->")[1].split("<!-- package-layers:end -->")[0]
    layers, upward = {}, set()
    for line in block.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 2 and cells[0].isdigit():
            for name in cells[1].replace("`", " ").split():
                layers["bev_mdo" if name == "bev_mdo" else f"bev_mdo.{name}"] = int(cells[0])
        elif line.startswith("- "):
            head = line[2:].split(":")[0]
            for pair in head.split(","):
                a, b = (p.strip().strip("`") for p in pair.split("->"))
                upward.add(tuple("bev_mdo" if n == "bev_mdo" else f"bev_mdo.{n}" for n in (a, b)))
    return layers, upward


def _unit(module: str, layers: dict[str, int]) -> str:
    """The documented package or module a module belongs to (bev_mdo.ros.evaluator -> bev_mdo.ros)."""
    parts = module.split(".")
    for k in range(len(parts), 0, -1):
        if ".".join(parts[:k]) in layers:
            return ".".join(parts[:k])
    raise AssertionError(f"{module} is in no layer of docs/architecture.md")


def test_the_package_layers_match_the_imports():
    layers, allowed = _package_layers()
    assert {"bev_mdo.cli", "bev_mdo.ros", "bev_mdo.mdo", "bev_mdo.models"} <= set(layers)
    mods = modules()
    top = {m for m in mods if m.count(".") == 1} | {"bev_mdo"}
    assert set(layers) == top, f"not documented: {top - set(layers)}; documented but missing: {set(layers) - top}"
    upward = set()
    for a, b in import_graph():
        ua, ub = _unit(a, layers), _unit(b, layers)
        if ua != ub and layers[ub] >= layers[ua]:
            upward.add((a, b))
    assert upward - allowed == set(), f"imports from the same or a higher layer than docs/architecture.md says: " \
                                      f"{sorted(upward - allowed)}"
    assert allowed - upward == set(), f"listed in docs/architecture.md but gone, remove them: {sorted(allowed - upward)}"


def test_the_floors_are_in_the_documented_order():
    """The floors the package is built on, bottom up: the table cannot be renumbered to let an
    upper floor's import pass (models and mdo at the bottom, then protocol, config, bag, ros, sessions, cli)."""
    layers, _ = _package_layers()
    floors = ["models", "mdo", "protocol", "config", "bag", "ros", "sessions", "cli"]
    got = [layers[f"bev_mdo.{f}"] for f in floors]
    assert got == sorted(got) and len(set(got)) == len(got), dict(zip(floors, got))
