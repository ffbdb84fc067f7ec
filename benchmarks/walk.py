"""The files one call of the pool runs code in, caller and workers alike, read off the running
code: a newcomer's walk of that call, made mechanical and repeatable.

    .venv/bin/python benchmarks/walk.py                 # one sync step() of the native game
    .venv/bin/python benchmarks/walk.py --call async    # one async send() + recv()

The native game, 64 envs, 2 workers, its pool reset and warmed up first.

* Python: every function of the package the call enters (``sys.setprofile``).
* Rust: callgrind (valgrind), with source lines, inlined code included. In the caller, the
  instructions inside the extension's method of the call; in the workers, those of the whole
  worker loop, in a run that makes the call 3 times against one that makes it once: the
  difference is what a call adds, start-up and the first reset cancel out.

A file counts once however many of its functions the call runs, however few instructions; the
game engine below ``Env::step`` is the env, not the pool, and is one row. Needs valgrind; builds the extension
unstripped into ``target/release`` (seconds after ``maturin develop --release``) and runs it
from a private copy of the package. Writes ``results/walk/walk-<call>.{md,json}`` (``--out``).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from common import write_results

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results" / "walk"
#: The extension's methods whose instructions are the caller's share of each call, by their
#: module and name (callgrind takes exact names here: of several wildcard patterns it honours
#: only the first).
METHODS = {
    "step": [("sync_api", "step")],
    "async": [("async_api", "send"), ("async_api", "recv")],
}
#: How many calls the long run makes against the short run's one.
LONG_RUN = 3

CHILD = r"""
import json, os, subprocess, sys
import numpy as np
import rogue_gym

call, mode, calls = sys.argv[1], sys.argv[2], int(sys.argv[3])
envs = rogue_gym.make_vec(64, config="paper", num_workers=2, seed=0,
                          start_timeout=600.0, step_timeout=600.0)
acts = np.random.default_rng(0).integers(0, 11, size=64)
ids = np.arange(64)

def one():
    if call == "step":
        envs.step(acts)
    else:
        envs.send(acts, ids)
        envs.recv()

if call == "step":
    envs.reset()
else:
    envs.async_reset()
    envs.recv()
if mode == "python":
    one()
    one()
    seen = {}
    def prof(frame, event, arg):
        if event == "call":
            seen.setdefault(frame.f_code.co_filename, set()).add(frame.f_code.co_name)
    sys.setprofile(prof)
    one()
    sys.setprofile(None)
    print(json.dumps({f: sorted(v) for f, v in seen.items()}))
else:
    for _ in range(calls):
        one()
    # The workers' counts, before close() (which gives a worker under valgrind too little
    # time to write them itself).
    me = str(os.getpid())
    for pid in os.listdir("/proc"):
        try:
            stat = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if pid.isdigit() and stat[1] == me:
            subprocess.run(["callgrind_control", "-d", pid], capture_output=True, timeout=300)
envs.close()
"""


def tracked_files() -> set[str]:
    """The repository's files (not the virtualenvs, builds and other files inside it)."""
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True)
    return set(out.stdout.split())


TRACKED = tracked_files()


def repo_path(path: str, package: Path) -> str | None:
    """``path`` as the repository names it (the private package copy mapped back), or ``None``
    for a file not of the repository."""
    p = Path(path)
    if not p.is_absolute():
        return None  # a system library's sources (glibc's debug info names them relative)
    for base, to in ((package, ROOT / "python"), (ROOT, ROOT)):
        try:
            rel = str((to / p.resolve().relative_to(base.resolve())).relative_to(ROOT))
        except ValueError:
            continue
        return rel if rel in TRACKED else None
    return None


def callgrind_costs(path: Path) -> collections.Counter[tuple[str, int]]:
    """Instructions per (source file, line) from one callgrind output file
    (``--dump-line=yes``), inlined code counted in its own file; code at line 0 (made by the
    compiler, of no source line) is left out."""
    names: dict[tuple[str, str], str] = {}
    cost: collections.Counter[tuple[str, int]] = collections.Counter()
    fl = fi = ""
    line_no = 0
    after_call = False

    def name(value: str, kind: str) -> str:
        m = re.match(r"\((\d+)\)(?: (.*))?$", value)
        if m is None:
            return value
        if m.group(2) is not None:
            names[(kind, m.group(1))] = m.group(2)
        return names.get((kind, m.group(1)), value)

    for line in path.read_text(errors="replace").splitlines():
        if not line:
            continue
        key, _, value = line.partition("=")
        if key == "fl":
            fl = fi = name(value, "fl")
        elif key in ("fi", "fe"):
            fi = name(value, "fl")
        elif key == "fn":
            name(value, "fn")
            fi = fl
        elif key in ("cfi", "cfl"):
            name(value, "fl")
        elif key == "cfn":
            name(value, "fn")
        elif key == "calls":
            after_call = True  # the next cost line is the callee's inclusive cost
        elif line[0].isdigit() or line[0] in "+-*":
            pos, *costs = line.split()
            if pos[0] == "+":
                line_no += int(pos[1:])
            elif pos[0] == "-":
                line_no -= int(pos[1:])
            elif pos != "*":
                line_no = int(pos)
            if after_call:
                after_call = False
                continue
            if costs and line_no != 0:
                cost[(fi, line_no)] += int(costs[0])
    return cost


def function_at(file: str, line: int, cache: dict[str, list[str]]) -> str:
    """The name of the Rust function whose body holds ``line`` of ``file`` (the nearest ``fn``
    above it), as a reader looks it up; ``"-"`` outside any."""
    if file not in cache:
        try:
            cache[file] = (ROOT / file).read_text().splitlines()
        except OSError:
            cache[file] = []
    src = cache[file]
    for i in range(min(line, len(src)) - 1, -1, -1):
        m = re.search(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)", src[i])
        if m and not src[i].lstrip().startswith("//"):
            return m.group(1)
    return "-"


def run_child(call: str, mode: str, calls: int, package: Path, valgrind: list[str]) -> str:
    env = dict(os.environ, PYTHONPATH=str(package))
    cmd = [*valgrind, sys.executable, "-c", CHILD, call, mode, str(calls)]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1200)
    if out.returncode != 0:
        raise SystemExit(f"walk: {' '.join(cmd[:3])} ... failed:\n{out.stderr[-3000:]}")
    return out.stdout


def rust_walk(
    call: str, package: Path, scratch: Path
) -> tuple[dict[str, int], dict[str, set[str]], dict[str, int], dict[str, set[str]]]:
    """The caller's and the workers' instructions per repository file for one call, and the
    functions they ran in."""
    sides: dict[int, list[Path]] = {}
    for calls in (1, LONG_RUN):
        out = scratch / f"cg-{calls}"
        out.mkdir()
        toggles = [
            f"--toggle-collect=_native::pool::{module}::<impl _native::pool::PyPool>::__pymethod_{m}__"
            for module, m in METHODS[call]
        ]
        valgrind = [
            "valgrind",
            "--tool=callgrind",
            "--trace-children=yes",
            "--collect-atstart=no",
            *toggles,
            "--toggle-collect=rogue_gym_pool::worker::worker_main",
            "--dump-line=yes",
            f"--callgrind-out-file={out}/cg.%p",
        ]
        run_child(call, "rust", calls, package, valgrind)
        sides[calls] = sorted(p for p in out.iterdir() if p.stat().st_size > 0)

    def side(paths: list[Path], worker: bool) -> collections.Counter[tuple[str, int]]:
        cost: collections.Counter[tuple[str, int]] = collections.Counter()
        for p in paths:
            is_worker = re.search(r"\.\d+\.\d+$", p.name) is not None  # by callgrind_control
            if is_worker != worker:
                continue
            for (file, line), n in callgrind_costs(p).items():
                rel = repo_path(file, package)
                if rel is not None:
                    cost[(rel, line)] += n
        return cost

    sources: dict[str, list[str]] = {}

    def by_file(cost: dict[tuple[str, int], int]) -> tuple[dict[str, int], dict[str, set[str]]]:
        files: collections.Counter[str] = collections.Counter()
        fns: dict[str, set[str]] = collections.defaultdict(set)
        for (file, line), n in cost.items():
            files[file] += n
            fns[file].add(function_at(file, line, sources))
        return dict(files), fns

    caller, caller_fns = by_file(side(sides[1], worker=False))
    long, short = side(sides[LONG_RUN], worker=True), side(sides[1], worker=True)
    # What the extra calls added, per call: a line whose count did not grow is not theirs.
    added = {k: (n - short.get(k, 0)) // (LONG_RUN - 1) for k, n in long.items()}
    workers, worker_fns = by_file({k: n for k, n in added.items() if n > 0})
    return caller, caller_fns, workers, worker_fns


def python_walk(call: str, package: Path) -> dict[str, list[str]]:
    """The package's files the call enters, with their functions."""
    seen = json.loads(run_child(call, "python", 1, package, []).strip().splitlines()[-1])
    out: dict[str, list[str]] = {}
    for file, fns in seen.items():
        rel = repo_path(file, package)
        if rel is not None:
            out[rel] = fns
    return out


def build_package(scratch: Path) -> Path:
    """A private copy of the package with the extension built unstripped (maturin strips it;
    callgrind needs the symbols and line tables)."""
    subprocess.run(
        ["cargo", "build", "--release", "--quiet", "-p", "rogue-gym-python"], cwd=ROOT, check=True
    )
    package = scratch / "python"
    shutil.copytree(
        ROOT / "python" / "rogue_gym",
        package / "rogue_gym",
        ignore=shutil.ignore_patterns("__pycache__", "*.so"),
    )
    shutil.copy(
        ROOT / "target" / "release" / "lib_native.so", package / "rogue_gym" / "_native.abi3.so"
    )
    return package


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--call", choices=sorted(METHODS), default="step")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    if shutil.which("valgrind") is None or shutil.which("callgrind_control") is None:
        raise SystemExit("walk: needs valgrind (callgrind): apt-get install valgrind")
    with tempfile.TemporaryDirectory(prefix="rogue-gym-walk-") as tmp:
        scratch = Path(tmp)
        print("== building the extension unstripped", flush=True)
        package = build_package(scratch)
        print(f"== Python side of one {args.call}", flush=True)
        py = python_walk(args.call, package)
        print(f"== Rust side (callgrind: 1 and {LONG_RUN} calls; about a minute)", flush=True)
        caller, caller_fns, workers, worker_fns = rust_walk(args.call, package, scratch)

    rows: list[dict[str, Any]] = []
    for file, fns in sorted(py.items()):
        rows.append({"side": "caller", "file": file, "instructions": None, "functions": fns})
    engine = {f: n for f, n in workers.items() if f.startswith("engine/")}
    for side, costs, names in (("caller", caller, caller_fns), ("worker", workers, worker_fns)):
        for file, n in sorted(costs.items()):
            if file.startswith("engine/"):
                continue
            mine = sorted(names[file])
            rows.append({"side": side, "file": file, "instructions": n, "functions": mine})
    if engine:
        rows.append(
            {
                "side": "worker",
                "file": "engine/ (the game's own step)",
                "instructions": sum(engine.values()),
                "functions": sorted(engine),
            }
        )
    files = sorted({r["file"] for r in rows})
    what = "one sync step()" if args.call == "step" else "one async send() + recv()"
    lines = [
        f"# The files {what} runs code in",
        "",
        f"The native game, 64 envs, 2 workers (`.venv/bin/python benchmarks/walk.py --call {args.call}`).",
        f"Files it runs code in: **{len(files)}** (the game engine below `Env::step` one of them).",
        "",
        "| side | file | instructions a call | functions |",
        "|---|---|---:|---|",
    ]
    for r in rows:
        n = "" if r["instructions"] is None else str(r["instructions"])
        fns = ", ".join(r["functions"][:8]) + (" ..." if len(r["functions"]) > 8 else "")
        lines.append(f"| {r['side']} | `{r['file']}` | {n} | {fns} |")
    md = "\n".join(lines)
    print(md)
    data = {"call": args.call, "files": files, "rows": rows}
    paths = write_results(args.out, f"walk-{args.call}", md, data)
    print("wrote", *paths)


if __name__ == "__main__":
    main()
