#!/usr/bin/env python3
"""Side-by-side throughput of vector envs hosting the same Rogue-Gym engine.

Backends (all play the paper config, 500-step episodes, random int64 actions pre-generated
with a fixed seed):

=================  ==========================================================================
``pool-sync``      our pool, gymnasium ``VectorEnv`` facade (``rogue_gym.make_vec``), ``step()``
``pool-async``     our pool, EnvPool-style ``send``/``recv`` with ``batch_size = num_envs / 2``
``gym-sync``       ``gymnasium.vector.SyncVectorEnv`` over ``rogue_gym.envs.RogueEnv``
``gym-async-shm``  ``gymnasium.vector.AsyncVectorEnv(shared_memory=True)`` over ``RogueEnv``
``sb3-dummy``      ``stable_baselines3`` ``DummyVecEnv`` over ``RogueEnv``
``sb3-subproc``    ``stable_baselines3`` ``SubprocVecEnv`` (forkserver) over ``RogueEnv``
=================  ==========================================================================

Protocol: every measurement ("cell": backend x
num_envs x observation encoding x repetition) runs in a fresh child process, so CPU time and
memory are attributable; set-up (process start) is timed separately and excluded. After a
warm-up, steps are taken for a fixed wall-clock window. Reported per cell: env steps/s (median
over repetitions, with min-max), p50/p99 latency of one ``step()`` (or one ``send``+``recv``),
CPU-seconds per env step (user+sys of the cell's process tree, read from ``/proc``, over the
window: parent plus workers), and peak RSS (sum of ``VmHWM`` over the process tree, which counts
shared pages once per process, so it overstates shared memory). The order of cells is shuffled
in every repetition, ``OMP_NUM_THREADS=1``, and the 1-minute load average is recorded before
each cell. A cell that exceeds ``--cell-timeout`` (start-up included) is killed and marked
``skipped`` in the table, and is not retried in later repetitions.

Usage::

    python benchmarks/vecenv_throughput.py                 # full sweep (by hand; ~1 h)
    python benchmarks/vecenv_throughput.py --short         # CI: seconds per cell
    python benchmarks/vecenv_throughput.py --short --num-envs 8 --obs symbol_index --reps 1 \\
        --out /tmp/bench

Python envs hosted in the pool (CartPole, ``RogueEnv`` as a Python env, a 1 ms env) against
SyncVectorEnv, AsyncVectorEnv, SubprocVecEnv and PufferLib: ``python
benchmarks/vecenv_throughput.py hosted [options]``, which runs ``hosted_throughput.py`` (its
options and outputs are documented there).

Outputs under ``--out`` (default ``benchmarks/results``): ``throughput.md`` (headline table at
64 envs with the pool / AsyncVectorEnv ratio, then every cell), ``throughput.png`` (steps/s vs
num_envs per encoding) and ``throughput.json`` (every repetition's raw numbers and the machine).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import random
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

from common import run_isolated, write_results
from vecenv_backends import (
    ACTION_SEED,
    BACKEND_LABELS,
    BACKENDS,
    ENCODINGS,
    FULL_NUM_ENVS,
    HEADLINE_ENVS,
    SHORT_NUM_ENVS,
    cell_main,
)

# ============================================================================================
# the sweep (parent process)


def load_average() -> float:
    """1-minute load average."""
    return os.getloadavg()[0]


def run_cell_subprocess(cell: Dict[str, Any], timeout: float) -> Dict[str, Any]:
    """Run one cell in a fresh interpreter (:func:`common.run_isolated`: its own session,
    killed whole after ``timeout``); its result."""
    cmd = [sys.executable, os.path.abspath(__file__), "--_cell", json.dumps(cell)]
    t0 = time.perf_counter()
    code, out, err = run_isolated(cmd, timeout, dict(os.environ))
    elapsed = time.perf_counter() - t0
    if code is None:
        return {"status": "skipped", "error": f"exceeded {timeout:.0f} s per cell"}
    for line in out.splitlines():
        if line.startswith("@@RESULT@@"):
            res = json.loads(line[len("@@RESULT@@") :])
            res["cell_wall_s"] = elapsed
            if res["status"] == "error":
                res["stderr_tail"] = err[-2000:]
            return res
    return {"status": "error", "error": f"child exited with {code}", "stderr_tail": err[-2000:]}


def machine_info() -> Dict[str, Any]:
    """CPU model, core count, kernel, versions."""
    info: Dict[str, Any] = {
        "cpu_model": platform.processor() or "?",
        "cores": os.cpu_count(),
        "kernel": platform.release(),
        "python": platform.python_version(),
        "load_average_start": os.getloadavg(),
        "mem_gib": None,
    }
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    info["cpu_model"] = line.split(":", 1)[1].strip()
                    break
        with open("/proc/meminfo") as f:
            info["mem_gib"] = round(int(f.readline().split()[1]) / 2**20, 1)
    except OSError:
        pass
    for mod in ("numpy", "gymnasium", "stable_baselines3", "torch", "rogue_gym"):
        try:
            m = __import__(mod)
            info[f"{mod}_version"] = getattr(m, "__version__", "?")
        except Exception:
            info[f"{mod}_version"] = None
    return info


def aggregate(runs: List[Dict[str, Any]]) -> Dict[Tuple[str, int, str], Dict[str, Any]]:
    """Group repetitions by (backend, num_envs, encoding): medians and min/max of steps/s."""
    groups: Dict[Tuple[str, int, str], List[Dict[str, Any]]] = {}
    for r in runs:
        groups.setdefault((r["backend"], r["num_envs"], r["encoding"]), []).append(r)
    out = {}
    for key, reps in groups.items():
        ok = [r for r in reps if r["status"] == "ok"]
        if not ok:
            bad = reps[-1]
            out[key] = {"status": bad["status"], "error": bad.get("error", ""), "reps": 0}
            continue
        sps = [r["steps_per_s"] for r in ok]

        def med(k: str, ok: List[Dict[str, Any]] = ok) -> float:
            return statistics.median(r[k] for r in ok)

        out[key] = {
            "status": "ok",
            "reps": len(ok),
            "steps_per_s": statistics.median(sps),
            "min": min(sps),
            "max": max(sps),
            "p50_ms": med("p50_ms"),
            "p99_ms": med("p99_ms"),
            "cpu_us_per_step": med("cpu_us_per_step"),
            "peak_rss_mib": med("peak_rss_mib"),
            "pss_mib": med("pss_mib"),
            "processes": med("processes"),
            "setup_s": med("setup_s"),
            "load": med("load_before"),
        }
    return out


def _fmt_int(x: float) -> str:
    return f"{x:,.0f}"


def render_markdown(
    agg: Dict[Tuple[str, int, str], Dict[str, Any]],
    backends: List[str],
    num_envs: List[int],
    encodings: List[str],
    meta: Dict[str, Any],
) -> str:
    """The headline table (64 envs, or the largest swept <= 64) and the table of every cell."""
    m = meta["machine"]
    lines = [
        "# Vector-env throughput: Rogue-Gym paper config, random actions",
        "",
        f"Machine: {m['cpu_model']}, {m['cores']} cores, {m['mem_gib']} GiB, Linux {m['kernel']}, "
        f"Python {m['python']}; load average at start {m['load_average_start'][0]:.2f} "
        f"(median per-cell load in the table). Command: `{meta['command']}`. "
        f"Mode: {meta['mode']}, {meta['reps']} repetition(s), {meta['seconds']} s window after "
        f"{meta['warmup']} warm-up batches, cell order shuffled per repetition. "
        f"Date {meta['date']}, commit {meta.get('commit', '?')}.",
        "",
    ]
    head_n = (
        HEADLINE_ENVS
        if HEADLINE_ENVS in num_envs
        else max([n for n in num_envs if n <= HEADLINE_ENVS] or num_envs)
    )
    lines += [
        f"## Headline: env steps/s at {head_n} envs (median of reps; ratio = pool / "
        "AsyncVectorEnv(shared_memory=True))",
        "",
        "| backend | " + " | ".join(encodings) + " |",
        "|---|" + "---:|" * len(encodings),
    ]
    for b in backends:
        cells = []
        for enc in encodings:
            a = agg.get((b, head_n, enc))
            cells.append(_fmt_int(a["steps_per_s"]) if a and a["status"] == "ok" else _status(a))
        lines.append(f"| {BACKEND_LABELS[b]} | " + " | ".join(cells) + " |")
    for b in ("pool-sync", "pool-async"):
        if b not in backends or "gym-async-shm" not in backends:
            continue
        cells = []
        for enc in encodings:
            a, base = agg.get((b, head_n, enc)), agg.get(("gym-async-shm", head_n, enc))
            if a and base and a["status"] == base["status"] == "ok":
                cells.append(f"**{a['steps_per_s'] / base['steps_per_s']:.1f}x**")
            else:
                cells.append("n/a")
        lines.append(f"| ratio {b} / gym-async-shm | " + " | ".join(cells) + " |")
    lines += [
        "",
        "## Every cell",
        "",
        "steps/s: median [min-max] over repetitions; latency of one `step()` (async: one "
        "`recv`+`send`, half the envs); CPU = user+sys of the process tree per env step; "
        "RSS = sum of peak RSS (VmHWM) over the process tree (shared pages counted once per "
        "process, so forked workers look bigger than they are); PSS = sum of proportional "
        "set sizes at the end of the window (shared pages split among their users); procs = "
        "processes in the tree; setup = construction + reset, excluded from the window.",
        "",
        "| encoding | envs | backend | steps/s | p50 ms | p99 ms | CPU µs/step | peak RSS MiB "
        "| PSS MiB | procs | setup s | load | reps |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for enc in encodings:
        for n in num_envs:
            for b in backends:
                a = agg.get((b, n, enc))
                if a is None:
                    continue
                if a["status"] != "ok":
                    lines.append(
                        f"| {enc} | {n} | {b} | **{a['status']}** ({a.get('error', '')}) "
                        "| | | | | | | | | 0 |"
                    )
                    continue
                lines.append(
                    f"| {enc} | {n} | {b} | {_fmt_int(a['steps_per_s'])} "
                    f"[{_fmt_int(a['min'])}-{_fmt_int(a['max'])}] | {a['p50_ms']:.3f} "
                    f"| {a['p99_ms']:.3f} | {a['cpu_us_per_step']:.1f} | {a['peak_rss_mib']:.0f} "
                    f"| {a['pss_mib']:.0f} | {a['processes']:.0f} | {a['setup_s']:.1f} "
                    f"| {a['load']:.2f} | {a['reps']} |"
                )
    lines.append("")
    return "\n".join(lines)


def _status(a: Optional[Dict[str, Any]]) -> str:
    if a is None:
        return "-"
    return f"**{a['status']}**"


def render_plot(
    agg: Dict[Tuple[str, int, str], Dict[str, Any]],
    backends: List[str],
    num_envs: List[int],
    encodings: List[str],
    path: Path,
) -> None:
    """steps/s vs num_envs (log-log), one panel per encoding, one line per backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    width = max(8.0, 5.2 * len(encodings))
    ncol = len(backends) if len(encodings) > 1 else 3
    rows = -(-len(backends) // ncol)
    fig, axes = plt.subplots(
        1, len(encodings), figsize=(width, 4.0 + 0.3 * rows), squeeze=False, sharey=True
    )
    for ax, enc in zip(axes[0], encodings):
        for b in backends:
            xs, ys, lo, hi = [], [], [], []
            for n in num_envs:
                a = agg.get((b, n, enc))
                if a and a["status"] == "ok":
                    xs.append(n)
                    ys.append(a["steps_per_s"])
                    lo.append(a["steps_per_s"] - a["min"])
                    hi.append(a["max"] - a["steps_per_s"])
            if xs:
                ax.errorbar(xs, ys, yerr=[lo, hi], marker="o", capsize=3, label=b)
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xticks(num_envs)
        ax.set_xticklabels([str(n) for n in num_envs])
        ax.set_title(enc)
        ax.set_xlabel("num_envs")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("env steps/s (median, min-max)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=9, frameon=False)
    fig.suptitle("Rogue-Gym paper config, random actions: vector-env throughput")
    fig.tight_layout(rect=(0, 0.05 + 0.045 * rows, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _csv_list(text: str, cast: Any = str) -> List[Any]:
    return [cast(x) for x in text.split(",") if x]


def _sweep_axes(runs: List[Dict[str, Any]]) -> Tuple[List[str], List[int], List[str]]:
    backends = [b for b in BACKENDS if any(r["backend"] == b for r in runs)]
    num_envs = sorted({int(r["num_envs"]) for r in runs})
    encodings = [e for e in ENCODINGS if any(r["encoding"] == e for r in runs)]
    return backends, num_envs, encodings


def rerender(json_path: Path, out: Path) -> int:
    """Write ``throughput.md`` and ``throughput.png`` under ``out`` from a saved JSON."""
    doc = json.loads(json_path.read_text())
    backends, num_envs, encodings = _sweep_axes(doc["runs"])
    agg = aggregate(doc["runs"])
    out.mkdir(parents=True, exist_ok=True)
    (out / "throughput.md").write_text(
        render_markdown(agg, backends, num_envs, encodings, doc["meta"])
    )
    render_plot(agg, backends, num_envs, encodings, out / "throughput.png")
    print(f"wrote {out / 'throughput.md'}, throughput.png")
    return 0


def _git_commit() -> str:
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            cwd=Path(__file__).resolve().parent,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the sweep and write ``throughput.{md,png,json}`` (``hosted ...``: the hosted-env
    benchmark)."""
    args_in = list(sys.argv[1:] if argv is None else argv)
    if args_in[:1] == ["hosted"]:
        script = str(Path(__file__).with_name("hosted_throughput.py"))
        return subprocess.run([sys.executable, script, *args_in[1:]], check=False).returncode
    p = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    p.add_argument("--short", action="store_true", help="CI mode: 1 rep, 1 s windows, 2 sizes")
    p.add_argument("--backends", type=_csv_list, default=BACKENDS)
    p.add_argument("--num-envs", type=functools.partial(_csv_list, cast=int), default=None)
    p.add_argument("--obs", type=_csv_list, default=None, help=f"subset of {ENCODINGS}")
    p.add_argument("--reps", type=int, default=None, help="repetitions (full 5, short 1)")
    p.add_argument("--seconds", type=float, default=None, help="timed window (full 2, short 1)")
    p.add_argument("--warmup", type=int, default=None, help="warm-up batches (full 50, short 5)")
    p.add_argument("--num-workers", type=int, default=None, help="pool workers (default: pool's)")
    p.add_argument("--cell-timeout", type=float, default=None, help="s per cell (full 240)")
    p.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results")
    p.add_argument("--seed", type=int, default=0, help="seed of the cell-order shuffles")
    p.add_argument(
        "--from-json",
        type=Path,
        default=None,
        help="re-render throughput.md/.png under --out from a saved throughput.json (no runs)",
    )
    p.add_argument("--_cell", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args._cell:
        return cell_main(args._cell)
    if args.from_json:
        return rerender(args.from_json, args.out)

    short = args.short
    backends = args.backends
    for b in backends:
        if b not in BACKENDS:
            p.error(f"unknown backend {b}; known {BACKENDS}")
    num_envs = args.num_envs or (SHORT_NUM_ENVS if short else FULL_NUM_ENVS)
    encodings = args.obs or (["symbol_onehot_u8"] if short else ENCODINGS)
    for e in encodings:
        if e not in ENCODINGS:
            p.error(f"unknown encoding {e}; known {ENCODINGS}")
    reps = args.reps or (1 if short else 5)
    seconds = args.seconds or (1.0 if short else 2.0)
    warmup = args.warmup if args.warmup is not None else (5 if short else 50)
    timeout = args.cell_timeout or (60.0 if short else 240.0)
    args.out.mkdir(parents=True, exist_ok=True)

    cells = [(b, n, e) for e in encodings for n in num_envs for b in backends]
    meta = {
        "command": "python " + " ".join([os.path.relpath(__file__), *list(argv or sys.argv[1:])]),
        "mode": "short" if short else "full",
        "reps": reps,
        "seconds": seconds,
        "warmup": warmup,
        "cell_timeout": timeout,
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "machine": machine_info(),
        "commit": _git_commit(),
        "action_seed": ACTION_SEED,
    }
    print(
        f"{len(cells)} cells x {reps} reps, {seconds} s windows; "
        f"{meta['machine']['cpu_model']}, {meta['machine']['cores']} cores, "
        f"load {load_average():.2f}",
        flush=True,
    )
    runs: List[Dict[str, Any]] = []
    dead: Dict[Tuple[str, int, str], Dict[str, Any]] = {}
    rng = random.Random(args.seed)
    total, done = len(cells) * reps, 0
    t_start = time.perf_counter()
    for rep in range(reps):
        order = cells[:]
        rng.shuffle(order)
        for b, n, e in order:
            done += 1
            base = {"backend": b, "num_envs": n, "encoding": e, "rep": rep}
            if (b, n, e) in dead:
                runs.append({**base, **dead[(b, n, e)], "load_before": load_average()})
                continue
            cell = {
                **base,
                "seconds": seconds,
                "warmup": warmup,
                "min_batches": 3,
                "num_workers": args.num_workers,
            }
            load = load_average()
            res = run_cell_subprocess(cell, timeout)
            runs.append({**base, **res, "load_before": load})
            if res["status"] == "ok":
                msg = (
                    f"{res['steps_per_s']:>11,.0f} steps/s  p50 {res['p50_ms']:.3f} ms  "
                    f"p99 {res['p99_ms']:.3f} ms  cpu {res['cpu_us_per_step']:.1f} us/step  "
                    f"rss {res['peak_rss_mib']:.0f} pss {res['pss_mib']:.0f} MiB  "
                    f"setup {res['setup_s']:.1f} s"
                )
            else:
                msg = f"{res['status'].upper()}: {res.get('error', '')}"
                if res["status"] == "skipped":
                    dead[(b, n, e)] = {"status": "skipped", "error": res["error"]}
                tail = res.get("stderr_tail", "").strip().splitlines()[-3:]
                msg += "".join("\n      " + t for t in tail)
            print(
                f"[{done:>3}/{total}] rep {rep + 1} {b:<14} n={n:<4} {e:<18} load {load:4.2f} "
                f"{msg}  ({time.perf_counter() - t_start:.0f} s)",
                flush=True,
            )

    agg = aggregate(runs)
    md = render_markdown(agg, backends, num_envs, encodings, meta)
    write_results(args.out, "throughput", md, {"meta": meta, "runs": runs})
    render_plot(agg, backends, num_envs, encodings, args.out / "throughput.png")
    print(md)
    print(f"wrote {args.out / 'throughput.md'}, throughput.png, throughput.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
