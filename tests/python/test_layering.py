"""The layering, read from the source. The package's import graph (type-only imports included)
has no circle, and each side imports only what it may (the kinds read a declared view,
``kinds/view.py``, and import nothing of the front; the protocol imports neither side; the worker's side
imports nothing of the caller's, and the caller's side imports one module of the worker's:
``worker/agent_rows.py``, which both run). In each Rust crate the modules that name each other
(``use`` and paths in code, a module and its own submodules one unit) form no circle, and no
source file is over 600 lines."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import rogue_gym

PACKAGE = Path(rogue_gym.__file__).parent
ROOT = Path(__file__).resolve().parents[2]
#: The Rust crates' source folders.
RUST_SOURCES = ("engine/src", "ipc/src", "pool/src", "pool/cli/src", "python/src")
MAX_RUST_LINES = 600


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _exists(module: str) -> bool:
    rel = Path(*module.split("."))
    base = PACKAGE.parent / rel
    if base.with_suffix(".py").exists() or (base / "__init__.py").exists():
        return True
    return base.with_suffix(".pyi").exists()  # an extension module (``_native``)


def import_graph() -> dict[str, set[str]]:
    """Each rogue_gym module and the rogue_gym modules it imports, anywhere in its source
    (under ``TYPE_CHECKING`` and inside functions too). ``from pkg import name`` counts as
    importing ``pkg.name`` when that is a module, else ``pkg``; the implicit run of parent
    packages' ``__init__`` is not an edge."""
    graph: dict[str, set[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = _module_name(path)
        is_pkg = path.name == "__init__.py"
        here = name.split(".") if is_pkg else name.split(".")[:-1]
        edges: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                edges.update(a.name for a in node.names if a.name.startswith("rogue_gym"))
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[: len(here) - node.level + 1]
                    mod = ".".join(base + ([node.module] if node.module else []))
                else:
                    mod = node.module or ""
                if not mod.startswith("rogue_gym"):
                    continue
                for alias in node.names:
                    sub = f"{mod}.{alias.name}"
                    edges.add(sub if _exists(sub) else mod)
        edges.discard(name)
        graph[name] = {e for e in edges if _exists(e)}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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
    return out


def test_the_import_graph_has_no_circle() -> None:
    graph = import_graph()
    assert len(graph) > 50  # the walk found the package
    assert _cycles(graph) == []


def _imports_of(prefix: str, graph: dict[str, set[str]]) -> set[str]:
    return {e for m, es in graph.items() if m == prefix or m.startswith(prefix + ".") for e in es}


def test_each_side_imports_only_what_it_may() -> None:
    graph = import_graph()
    kinds = _imports_of("rogue_gym.kinds", graph)
    assert {e for e in kinds if e.startswith("rogue_gym.front")} == set()
    protocol = _imports_of("rogue_gym.protocol", graph)
    sides = ("rogue_gym.front", "rogue_gym.kinds", "rogue_gym.worker")
    assert {e for e in protocol if e.startswith(sides)} == set()
    worker = _imports_of("rogue_gym.worker", graph)
    assert {e for e in worker if e.startswith(("rogue_gym.front", "rogue_gym.kinds"))} == set()
    callers = {m: es for m, es in graph.items() if not m.startswith("rogue_gym.worker")}
    of_worker = {e for es in callers.values() for e in es if e.startswith("rogue_gym.worker")}
    assert of_worker == {"rogue_gym.worker.agent_rows"}, of_worker


def test_a_kind_has_at_most_nine_members() -> None:
    from rogue_gym.kinds.spec import Kind
    from rogue_gym.kinds.view import PoolView

    def members(proto: type) -> set[str]:
        own = set(vars(proto)) | set(getattr(proto, "__annotations__", {}))
        return {m for m in own if not m.startswith("_")}

    assert len(members(Kind)) <= 9, sorted(members(Kind))
    assert len(members(PoolView)) <= 10, sorted(members(PoolView))


def test_no_benchmark_imports_another() -> None:
    """Benchmark scripts share ``common.py`` and their own ``*_backends.py`` only."""
    bench = Path(__file__).resolve().parents[2] / "benchmarks"
    scripts = {p.stem for p in bench.glob("*.py")}
    assert {"common", "real_envs_backends", "vecenv_backends"} <= scripts
    libraries = {s for s in scripts if s == "common" or s.endswith("_backends")}
    wrong = {}
    for path in bench.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom) and not node.level
                else []
            )
            bad = [n for n in names if n.split(".")[0] in scripts - libraries]
            if bad:
                wrong[path.name] = bad
    assert wrong == {}


def _rust_module(src: Path, path: Path) -> tuple[str, ...]:
    parts = path.relative_to(src).with_suffix("").parts
    if parts[-1] in ("mod", "lib", "main"):
        parts = parts[:-1]
    return tuple(parts)


def _expand(tree: str) -> list[str]:
    """The paths of a ``use`` tree: ``a::{b, c::{d}}`` is ``a::b`` and ``a::c::d``."""
    tree = re.sub(r"\s+", "", tree)
    if "{" not in tree:
        return [tree]
    head, _, rest = tree.partition("{")
    inner, depth, parts, cur = rest[: rest.rindex("}")], 0, [], ""
    for ch in inner:
        depth += ch == "{"
        depth -= ch == "}"
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    return [p for part in parts if part for p in _expand(head + part)]


def rust_module_graph(src: Path) -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    """Each module of the crate at ``src`` and the modules it names (in a ``use`` or a
    ``crate::``/``super::``/``self::`` path in code, its unit tests left out), but for its own
    ancestors and submodules."""
    files = {_rust_module(src, p): p for p in sorted(src.rglob("*.rs"))}
    graph: dict[tuple[str, ...], set[tuple[str, ...]]] = {}
    for module, path in files.items():
        text = path.read_text().split("#[cfg(test)]\nmod tests")[0]
        code = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("//"))
        paths = [
            p
            for tree in re.findall(r"^\s*(?:pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", code, re.M)
            for p in _expand(tree)
        ]
        paths += re.findall(r"\b(?:crate|super|self)(?:::[A-Za-z_]\w*)+", code)
        edges = set()
        for p in paths:
            head, *segments = p.split("::")
            if head == "crate":
                at: tuple[str, ...] = ()
            elif head == "super":
                at = module[:-1]
            elif head == "self":
                at = module
            elif (*module, head) in files:
                at = (*module, head)
            else:
                continue  # another crate's
            for seg in segments:
                if (*at, seg) not in files:
                    break
                at += (seg,)
            near = at[: len(module)] == module or module[: len(at)] == at
            if not near:
                edges.add(at)
        graph[module] = edges
    return graph


def test_no_rust_crate_has_a_circle_of_modules() -> None:
    for src in RUST_SOURCES:
        graph = rust_module_graph(ROOT / src)
        assert len(graph) > 3, src  # the walk found the crate
        circles = _cycles({"::".join(m): {"::".join(e) for e in es} for m, es in graph.items()})
        assert circles == [], (src, circles)


def test_no_rust_source_file_is_over_600_lines() -> None:
    long = {
        str(path.relative_to(ROOT)): n
        for src in RUST_SOURCES
        for path in (ROOT / src).rglob("*.rs")
        if (n := len(path.read_text().splitlines())) > MAX_RUST_LINES
    }
    assert long == {}, f"split these by job (at most {MAX_RUST_LINES} lines a file): {long}"
