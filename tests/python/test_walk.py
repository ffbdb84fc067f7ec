"""benchmarks/walk.py reads callgrind's counts as the files that hold the code: what its count of
the files one call crosses rests on."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]


def load_walk() -> ModuleType:
    sys.path.insert(0, str(ROOT / "benchmarks"))  # its `common`
    try:
        spec = importlib.util.spec_from_file_location("walk", ROOT / "benchmarks" / "walk.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))


# Names compressed as callgrind writes them, lines relative (+n, -n), code inlined from another
# file (fi/fe), compiler code at line 0, and a call whose inclusive cost follows `calls=`.
CALLGRIND = """\
version: 1
positions: line
events: Ir

fl=(1) /r/a.rs
fn=(1) outer
10 5
+2 3
fi=(2) /r/b.rs
20 7
fe=(1)
-8 1
0 4
cfl=(2)
cfn=(2) callee
calls=1 20
12 100
fl=(2)
fn=(2)
20 9
"""


def test_instructions_count_where_their_source_line_is(tmp_path: Path) -> None:
    walk = load_walk()
    out = tmp_path / "callgrind.out"
    out.write_text(CALLGRIND)
    assert dict(walk.callgrind_costs(out)) == {
        ("/r/a.rs", 10): 5,
        ("/r/a.rs", 12): 3 + 1,  # +2 from 10, then -8 from the inlined line 20
        ("/r/b.rs", 20): 7 + 9,  # inlined into `outer`, and in `callee` itself
    }


def test_a_line_is_named_by_the_function_whose_body_holds_it() -> None:
    walk = load_walk()
    file = "pool/src/supervisor/stepping.rs"
    lines = (ROOT / file).read_text().splitlines()
    at = next(i for i, text in enumerate(lines, 1) if "fn collect(" in text)
    assert walk.function_at(file, at + 3, {}) == "collect"
    assert walk.function_at(file, 1, {}) == "-"  # the module doc, before any function


def test_only_the_repositorys_own_files_are_counted(tmp_path: Path) -> None:
    walk = load_walk()
    package = tmp_path / "python"
    (package / "rogue_gym" / "front").mkdir(parents=True)
    copied = package / "rogue_gym" / "front" / "core.py"
    assert walk.repo_path(str(copied), package) == "python/rogue_gym/front/core.py"
    assert walk.repo_path(str(ROOT / "pool" / "src" / "lib.rs"), package) == "pool/src/lib.rs"
    assert walk.repo_path(str(ROOT / ".venv" / "lib" / "numpy.py"), package) is None
    assert walk.repo_path("malloc/malloc.c", package) is None  # glibc names its own relative
