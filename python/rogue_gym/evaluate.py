"""Generalization evaluator: score a policy on a frozen suite's test seeds through the pool.

Command line::

    python -m rogue_gym.evaluate --suite paper-40 --policy random
    python -m rogue_gym.evaluate --suite paper-40 --policy my_pkg.agents:policy \\
        [--episodes-per-seed 10] [--num-envs 64] [--num-workers 2] [--seeds-limit 50] \\
        [--out DIR] [--policy-seed 0] [--confidence 0.95]
    python -m rogue_gym.evaluate --suite paper-40 --manifest-only [--out DIR]

What it reports (printed, and written under ``--out``):

* ``per_seed.csv``: one row per test seed: the policy's mean/std/min/max return over the
  seed's episodes, the random agent's mean on the same seed, and the seed's difficulty
  metadata (see :func:`seed_manifest`).
* ``summary.json``: the suite (with its digest), the settings, the per-episode returns of
  both agents as ``(seeds, episodes)`` arrays, and for each agent the mean over seeds with a
  bootstrap confidence interval **across seeds** (per-seed means are resampled, never single
  episodes: episodes of one seed are not independent samples of the benchmark).
* ``manifest.csv`` / ``manifest.json`` with ``--manifest-only``.

The random agent is always scored on the same seeds in the same run (unless the policy *is*
the random agent), so the two numbers are directly comparable.

**Policy interface.** ``--policy module:attr`` (or ``path/to/file.py:attr``) names a Python
object. If it is a class it is instantiated with no arguments. The result must be callable as
``policy(obs) -> actions``: ``obs`` is a numpy array of shape ``(N, *obs_shape)`` (one row per
environment of the pool, in environment order; the encoding is ``--obs ENCODING[:DTYPE]``,
default ``symbol_onehot`` in uint8, ``symbol_onehot:float32`` for the paper's input), and
``actions`` an integer array-like of shape ``(N,)`` with values in ``[0, 11)``. The array
``obs`` is only valid during the call: copy what you keep. If the policy has a
``seed(seed: int)`` method it is called once before evaluation with ``--policy-seed``; a
policy must be deterministic given that seed, and then the whole evaluation is: the pool's
episodes are a pure function of the seed schedule, independent of the number of workers.
A policy with a ``required_obs`` attribute is given that encoding whatever ``--obs`` says.
``--policy checkpoint:RUN/models/frames-N.pt`` scores a network saved by ``rogue_gym.train``
(:mod:`rogue_gym.train.posthoc`; it reads symbol indices).

**Episode schedule.** With ``K`` test seeds and ``E`` episodes per seed, the evaluator hands
the pool the seed list with the sequential (round-robin) seed policy: environment ``i``'s
``e``-th episode has schedule index ``j = i + e * N`` and plays ``seeds[j % K]``. The first
``M = K * E`` indices cover every seed exactly ``E`` times; episodes with ``j >= M`` are played
out (the pool steps all environments together) but discarded. Results therefore depend on
``(policy, policy seed, num_envs)`` but never on the number of workers.
"""

from __future__ import annotations

import argparse
import csv
import importlib
import importlib.util
import inspect
import json
import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import _native
from .suites import Suite, get_suite, suite_names

__all__ = [
    "NUM_ACTIONS",
    "AgentResult",
    "RandomPolicy",
    "bootstrap_ci",
    "evaluate",
    "load_policy",
    "main",
    "run_episodes",
    "seed_manifest",
]

#: Size of the action space (``. h j k l n b u y > s``).
NUM_ACTIONS: int = _native.NUM_ACTIONS

Policy = Callable[[np.ndarray], Any]


# --------------------------------------------------------------------------------------------
# statistics


def bootstrap_ci(
    values: Sequence[float],
    confidence: float = 0.95,
    n_resamples: int = 10_000,
    seed: int = 0,
) -> Tuple[float, float, float]:
    """Percentile-bootstrap confidence interval of the mean of ``values``.

    ``values`` are per-seed means (one number per test seed): the interval is across seeds.
    The resampling RNG is ``numpy.random.default_rng(seed)``, so the result is reproducible.

    Returns ``(mean, low, high)``. One value gives a zero-width interval at that value; no
    value raises ``ValueError``.
    """
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size == 0:
        raise ValueError("bootstrap_ci needs at least one value")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    mean = float(x.mean())
    if x.size == 1 or np.all(x == x[0]):
        return mean, mean, mean
    rng = np.random.default_rng(seed)
    means = np.empty(n_resamples, dtype=np.float64)
    # Chunked so that 10k resamples of 1000 seeds stay ~ 8 MB at a time.
    chunk = max(1, 1_000_000 // x.size)
    for start in range(0, n_resamples, chunk):
        stop = min(n_resamples, start + chunk)
        idx = rng.integers(0, x.size, size=(stop - start, x.size))
        means[start:stop] = x[idx].mean(axis=1)
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(means, [alpha, 1.0 - alpha])
    # Quantiles of a finite resample can miss the sample mean by rounding only when the
    # interval is degenerate; clamp so that low <= mean <= high always holds.
    return mean, float(min(low, mean)), float(max(high, mean))


# --------------------------------------------------------------------------------------------
# policies


class RandomPolicy:
    """Uniform random actions over the 11 actions, from its own seeded numpy RNG."""

    def __init__(self, seed: int = 0, num_actions: int = NUM_ACTIONS) -> None:
        self.num_actions = num_actions
        self.seed(seed)

    def seed(self, seed: int) -> None:
        """Restart the action stream from ``seed``."""
        self._rng = np.random.default_rng(seed)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """One uniform action per row of ``obs``."""
        return self._rng.integers(0, self.num_actions, size=len(obs), dtype=np.int64)


#: What loads ``checkpoint:PATH`` policies (a saved network of ``rogue_gym.train``, needs
#: torch: ``RUN/models/frames-N.pt``), by name: the trainer builds on this evaluator, not the
#: other way round.
CHECKPOINT_LOADER = ("rogue_gym.train.posthoc", "checkpoint_policy")


def load_policy(spec: str) -> Policy:
    """Resolve ``random``, ``module:attr`` or ``path/to/file.py:attr`` into a policy callable.

    Classes are instantiated with no arguments. See the module docstring for the interface.
    """
    if spec == "random":
        return RandomPolicy()
    if spec.startswith("checkpoint:"):
        loader_module, loader_name = CHECKPOINT_LOADER
        loader = getattr(importlib.import_module(loader_module), loader_name)
        return loader(Path(spec.split(":", 1)[1]))
    if ":" not in spec:
        raise ValueError(f"--policy must be 'random' or 'module:attr', got {spec!r}")
    mod_name, attr = spec.rsplit(":", 1)
    if mod_name.endswith(".py"):
        path = Path(mod_name)
        mod_spec = importlib.util.spec_from_file_location(path.stem, path)
        if mod_spec is None or mod_spec.loader is None:
            raise ImportError(f"cannot load policy file {path}")
        module = importlib.util.module_from_spec(mod_spec)
        mod_spec.loader.exec_module(module)
    else:
        module = importlib.import_module(mod_name)
    obj: Any = module
    for part in attr.split("."):
        obj = getattr(obj, part)
    if inspect.isclass(obj):
        obj = obj()
    if not callable(obj):
        raise TypeError(f"policy {spec!r} is not callable")
    return obj


def _seed_policy(policy: Policy, seed: int) -> None:
    seeder = getattr(policy, "seed", None)
    if callable(seeder):
        seeder(seed)


# --------------------------------------------------------------------------------------------
# running episodes through the pool


def _obs_kwargs(obs: str) -> Dict[str, Any]:
    """``"symbol_onehot"`` or ``"symbol_onehot:float32"`` -> ``{"obs": ..., "dtype": ...}``."""
    name, _, dtype = obs.partition(":")
    return {"obs": name, "dtype": dtype or "uint8"}


def _make_pool(
    suite: Suite,
    seeds: List[int],
    num_envs: int,
    num_workers: Optional[int],
    obs: str,
) -> Any:
    """A gymnasium VectorEnv over the pool playing ``seeds`` round-robin (see module doc)."""
    from gymnasium.vector import AutoresetMode

    from . import make_vec  # imported late: the pure-Python parts work without the extension

    kwargs: Dict[str, Any] = {
        "config": suite.config,
        "max_steps": suite.max_steps,
        "stair_reward": suite.stair_reward,
        "seeds": seeds,
        "seed_policy": "sequential",
        **_obs_kwargs(obs),
        "autoreset_mode": AutoresetMode.SAME_STEP,
        # A restarted worker would cut episodes short: an evaluation must fail loudly instead.
        "on_worker_failure": "raise",
    }
    if num_workers is not None:
        kwargs["num_workers"] = num_workers
    return make_vec(num_envs, **kwargs)


class InProcessVec:
    """The pool's evaluation semantics with ``RogueEnv`` games in this process (no workers).

    Same seed schedule (sequential round-robin over ``seeds``) and same-step autoreset as the
    pool, so given the same policy it yields the same returns: a cross-check of the pool, and
    a fallback where worker processes are unwanted (``--backend inprocess``).
    """

    def __init__(self, suite: Suite, seeds: List[int], num_envs: int, obs: str) -> None:
        from .envs import RogueEnv

        self.seeds = list(seeds)
        self.num_envs = num_envs
        self.envs = [
            RogueEnv(
                config_dict=suite.config,
                max_steps=suite.max_steps,
                stair_reward=suite.stair_reward,
                **_obs_kwargs(obs),
            )
            for _ in range(num_envs)
        ]
        self.episode = [0] * num_envs

    def _seed(self, i: int) -> int:
        return self.seeds[(i + self.episode[i] * self.num_envs) % len(self.seeds)]

    def reset(self) -> Tuple[np.ndarray, Dict[str, Any]]:
        """Start every env's first scheduled episode."""
        self.episode = [0] * self.num_envs
        obs = [e.reset(options={"episode_seed": self._seed(i)})[0] for i, e in enumerate(self.envs)]
        return np.stack(obs), {}

    def step(self, actions: np.ndarray) -> Tuple[Any, ...]:
        """Step every env; an ended episode is replaced by the next scheduled one at once."""
        obs, rew = [], np.zeros(self.num_envs)
        term = np.zeros(self.num_envs, bool)
        trunc = np.zeros(self.num_envs, bool)
        for i, env in enumerate(self.envs):
            o, r, te, tr, _ = env.step(int(actions[i]))
            rew[i], term[i], trunc[i] = r, te, tr
            if te or tr:
                self.episode[i] += 1
                o, _ = env.reset(options={"episode_seed": self._seed(i)})
            obs.append(o)
        return np.stack(obs), rew, term, trunc, {}

    def close(self) -> None:
        """Nothing to release."""


def run_episodes(
    suite: Suite,
    policy: Policy,
    seeds: Sequence[int],
    episodes_per_seed: int,
    num_envs: int = 16,
    num_workers: Optional[int] = None,
    obs: str = "symbol_onehot",
    policy_seed: int = 0,
    progress: bool = True,
    desc: str = "",
    backend: str = "pool",
) -> np.ndarray:
    """Play ``episodes_per_seed`` episodes on each of ``seeds`` and return the returns.

    Returns a float64 array of shape ``(len(seeds), episodes_per_seed)``: row ``k`` holds the
    returns of the episodes played on ``seeds[k]``, in schedule order. ``backend`` is
    ``"pool"`` (worker processes, the default) or ``"inprocess"`` (:class:`InProcessVec`).
    """
    seeds = [int(s) for s in seeds]
    k, e_per = len(seeds), int(episodes_per_seed)
    if k == 0 or e_per <= 0:
        raise ValueError("need at least one seed and one episode per seed")
    total = k * e_per
    # No more envs than episodes; keep a multiple of the worker count (the pool needs one).
    num_envs = max(1, min(int(num_envs), total))
    if num_workers is not None and backend == "pool":
        w = int(num_workers)
        num_envs = max(w, num_envs // w * w)
    _seed_policy(policy, policy_seed)
    returns = np.full(total, np.nan, dtype=np.float64)
    if backend == "pool":
        env = _make_pool(suite, seeds, num_envs, num_workers, obs)
    elif backend == "inprocess":
        env = InProcessVec(suite, seeds, num_envs, obs)
    else:
        raise ValueError(f"backend must be 'pool' or 'inprocess', got {backend!r}")
    bar = _progress(total, desc, progress)
    try:
        obs_batch, _ = env.reset()
        ep_index = np.arange(num_envs, dtype=np.int64)  # schedule index of each env's episode
        ep_return = np.zeros(num_envs, dtype=np.float64)
        done_count = 0
        while done_count < total:
            actions = np.asarray(policy(obs_batch), dtype=np.int64).reshape(num_envs)
            obs_batch, reward, terminated, truncated, info = env.step(actions)
            ep_return += np.asarray(reward, dtype=np.float64)
            finished = np.flatnonzero(np.logical_or(terminated, truncated))
            played = _final_seeds(info)
            for i in finished:
                j = int(ep_index[i])
                if played is not None and int(played[i]) != seeds[j % k]:
                    raise RuntimeError(
                        f"env {i} played seed {int(played[i])}, the schedule says {seeds[j % k]}"
                    )
                if j < total:
                    returns[j] = ep_return[i]
                    done_count += 1
                    bar.update(1)
                ep_return[i] = 0.0
                ep_index[i] += num_envs
    finally:
        bar.close()
        env.close()
    # schedule index j = r * k + s  ->  (seed s, repetition r)
    return returns.reshape(e_per, k).T.copy()


def _final_seeds(info: Any) -> Optional[np.ndarray]:
    """The seeds of the episodes that just ended, when the vector env reports them."""
    final = info.get("final_info") if isinstance(info, dict) else None
    if isinstance(final, dict) and "seed" in final:
        return np.asarray(final["seed"])
    return None


class _NoBar:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def _progress(total: int, desc: str, enabled: bool) -> Any:
    if not enabled:
        return _NoBar()
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is a dev dependency
        return _NoBar()
    # Redraw at most every 0.1 s on a terminal, every 5 s into a log file.
    interval = 0.1 if sys.stderr.isatty() else 5.0
    return tqdm(
        total=total,
        desc=desc,
        unit="ep",
        dynamic_ncols=True,
        file=sys.stderr,
        mininterval=interval,
    )


# --------------------------------------------------------------------------------------------
# manifest (difficulty metadata per seed)


def seed_manifest(suite: Suite, seeds: Sequence[int]) -> List[Dict[str, Any]]:
    """Difficulty metadata of level 1 of each seed, from the engine's floor summary.

    One dict per seed with the keys returned by
    ``rogue_gym._native.floor_summary(config_json, seed)``: ``rooms`` (real rooms),
    ``normal_rooms``, ``maze_rooms``, ``dark_rooms``, ``gone_rooms``, ``doors``,
    ``hidden_doors`` (secret doors), ``passage_cells``, ``hidden_passages`` (hidden passage
    cells), ``gold_piles``, ``gold_total``, ``stairs_distance`` (shortest walk in moves from
    the start cell to the stairs under the movement rule, without searching; ``None`` when
    the stairs need a search) and ``stairs_distance_unhidden`` (the same with every hidden
    feature found). Exact definitions: ``engine/src/summary.rs``.
    """
    from . import _native

    config_json = suite.config_json()
    rows = []
    for s in seeds:
        row: Dict[str, Any] = {"seed": int(s)}
        row.update(_native.floor_summary(config_json, int(s)))
        row.pop("level", None)
        rows.append(row)
    return rows


# --------------------------------------------------------------------------------------------
# the whole evaluation


@dataclass
class AgentResult:
    """Scores of one agent on a suite's (possibly limited) test seeds."""

    name: str
    returns: np.ndarray  # (seeds, episodes)
    mean: float
    ci_low: float
    ci_high: float
    seed_std: float

    @classmethod
    def from_returns(
        cls, name: str, returns: np.ndarray, confidence: float, bootstrap_seed: int
    ) -> AgentResult:
        """Summarise ``(seeds, episodes)`` returns: per-seed means, then the bootstrap CI."""
        per_seed = returns.mean(axis=1)
        mean, lo, hi = bootstrap_ci(per_seed, confidence=confidence, seed=bootstrap_seed)
        std = float(per_seed.std(ddof=1)) if per_seed.size > 1 else 0.0
        return cls(name, returns, mean, lo, hi, std)

    def line(self, confidence: float) -> str:
        """``name: mean [lo, hi] (95% CI across N seeds)``."""
        half = (self.ci_high - self.ci_low) / 2.0
        return (
            f"{self.name}: {self.mean:.2f} ± {half:.2f} "
            f"[{self.ci_low:.2f}, {self.ci_high:.2f}] "
            f"({confidence:.0%} bootstrap CI across {self.returns.shape[0]} seeds, "
            f"{self.returns.shape[1]} episodes each)"
        )

    def to_json(self) -> Dict[str, Any]:
        """JSON-able summary with the raw returns."""
        return {
            "name": self.name,
            "mean": self.mean,
            "ci_low": self.ci_low,
            "ci_high": self.ci_high,
            "per_seed_std": self.seed_std,
            "per_seed_mean": self.returns.mean(axis=1).tolist(),
            "returns": self.returns.tolist(),
        }


def evaluate(
    suite: Suite,
    policy_spec: str = "random",
    policy: Optional[Policy] = None,
    episodes_per_seed: Optional[int] = None,
    num_envs: int = 16,
    num_workers: Optional[int] = None,
    seeds_limit: Optional[int] = None,
    obs: str = "symbol_onehot",
    policy_seed: int = 0,
    confidence: float = 0.95,
    bootstrap_seed: int = 0,
    with_random: bool = True,
    with_manifest: bool = True,
    progress: bool = True,
    backend: str = "pool",
) -> Dict[str, Any]:
    """Evaluate a policy on ``suite``; returns the summary dict written to ``summary.json``.

    ``policy`` (a callable) takes precedence over ``policy_spec``. ``seeds_limit`` keeps the
    first K test seeds (quick runs; say so when quoting numbers).
    """
    if policy is None:
        policy = load_policy(policy_spec)
    # A policy that reads one observation only (a trained network: symbol indices) says so.
    obs = getattr(policy, "required_obs", obs)
    is_random = policy_spec == "random" and isinstance(policy, RandomPolicy)
    seeds = suite.test_seed_list()
    if seeds_limit is not None:
        seeds = seeds[: int(seeds_limit)]
    e_per = int(episodes_per_seed or suite.episodes_per_seed)
    common: Dict[str, Any] = dict(
        suite=suite,
        seeds=seeds,
        episodes_per_seed=e_per,
        num_envs=num_envs,
        num_workers=num_workers,
        obs=obs,
        policy_seed=policy_seed,
        progress=progress,
        backend=backend,
    )
    t0 = time.perf_counter()
    agents = [
        AgentResult.from_returns(
            "random" if is_random else policy_spec,
            run_episodes(policy=policy, desc=f"{suite.name} policy", **common),
            confidence,
            bootstrap_seed,
        )
    ]
    if with_random and not is_random:
        rnd = run_episodes(policy=RandomPolicy(), desc=f"{suite.name} random", **common)
        agents.append(AgentResult.from_returns("random", rnd, confidence, bootstrap_seed))
    elapsed = time.perf_counter() - t0
    manifest: List[Dict[str, Any]] = []
    if with_manifest:
        try:
            manifest = seed_manifest(suite, seeds)
        except (ImportError, AttributeError) as exc:
            print(f"note: no seed manifest ({exc})", file=sys.stderr)
    return {
        "suite": suite.canonical() | {"digest": suite.digest(), "description": suite.description},
        "settings": {
            "policy": policy_spec,
            "policy_seed": policy_seed,
            "episodes_per_seed": e_per,
            "seeds": seeds,
            "seeds_limit": seeds_limit,
            "num_envs": num_envs,
            "num_workers": num_workers,
            "obs": obs,
            "backend": backend,
            "confidence": confidence,
            "bootstrap_seed": bootstrap_seed,
            "bootstrap_resamples": 10_000,
            "elapsed_s": round(elapsed, 3),
            "python": platform.python_version(),
            "host": platform.node(),
        },
        "agents": [a.to_json() for a in agents],
        "manifest": manifest,
        "_agents": agents,
    }


# --------------------------------------------------------------------------------------------
# output


def _write_csv(path: Path, rows: List[Dict[str, Any]]) -> None:
    if not rows:
        return
    fields: List[str] = []
    for row in rows:
        for key in row:
            if key not in fields:
                fields.append(key)
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)


def _compact_json(doc: Dict[str, Any]) -> str:
    """One line per top-level key: readable, without one line per number."""
    body = ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in doc.items())
    return "{\n" + body + "\n}\n"


def per_seed_rows(result: Dict[str, Any]) -> List[Dict[str, Any]]:
    """One row per seed: each agent's mean/std/min/max, then the manifest columns."""
    seeds = result["settings"]["seeds"]
    manifest = {m["seed"]: m for m in result.get("manifest", [])}
    rows = []
    for k, s in enumerate(seeds):
        row: Dict[str, Any] = {"seed": s}
        for a_i, agent in enumerate(result["agents"]):
            r = np.asarray(agent["returns"][k], dtype=np.float64)
            prefix = "policy" if a_i == 0 else agent["name"]
            row[f"{prefix}_mean"] = round(float(r.mean()), 4)
            row[f"{prefix}_std"] = round(float(r.std()), 4)
            row[f"{prefix}_min"] = float(r.min())
            row[f"{prefix}_max"] = float(r.max())
        for key, val in manifest.get(s, {}).items():
            if key != "seed":
                row[key] = val
        rows.append(row)
    return rows


def write_results(result: Dict[str, Any], out: Path) -> List[Path]:
    """Write ``per_seed.csv`` and ``summary.json`` under ``out``; returns the paths."""
    out.mkdir(parents=True, exist_ok=True)
    per_seed = out / "per_seed.csv"
    _write_csv(per_seed, per_seed_rows(result))
    summary = out / "summary.json"
    clean = {k: v for k, v in result.items() if not k.startswith("_")}
    summary.write_text(_compact_json(clean))
    return [per_seed, summary]


def write_manifest(rows: List[Dict[str, Any]], out: Path) -> List[Path]:
    """Write ``manifest.csv`` and ``manifest.json`` under ``out``; returns the paths."""
    out.mkdir(parents=True, exist_ok=True)
    csv_path, json_path = out / "manifest.csv", out / "manifest.json"
    _write_csv(csv_path, rows)
    json_path.write_text("[\n" + ",\n".join(json.dumps(r) for r in rows) + "\n]\n")
    return [csv_path, json_path]


def _describe_manifest(rows: List[Dict[str, Any]]) -> str:
    lines = []
    for key in rows[0]:
        if key == "seed":
            continue
        vals = np.asarray([r[key] for r in rows if r[key] is not None], dtype=np.float64)
        if vals.size:
            missing = len(rows) - vals.size
            note = f"  ({missing} seeds: none)" if missing else ""
            lines.append(
                f"  {key:24s} mean {vals.mean():8.3f}  min {vals.min():6g}  max {vals.max():6g}"
                + note
            )
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# CLI


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.evaluate",
        description="Score a policy on a frozen Rogue-Gym generalization suite's test seeds.",
    )
    p.add_argument("--suite", required=True, choices=suite_names())
    p.add_argument(
        "--policy",
        default="random",
        help="'random', 'module:attr' or 'checkpoint:RUN/models/frames-N.pt' (see docs)",
    )
    p.add_argument("--policy-seed", type=int, default=0)
    p.add_argument("--episodes-per-seed", type=int, default=None, help="default: the suite's")
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--num-workers", type=int, default=None, help="default: the pool's")
    p.add_argument("--seeds-limit", type=int, default=None, help="first K test seeds only")
    p.add_argument(
        "--obs",
        default="symbol_onehot",
        help="observation for the policy: ENCODING[:DTYPE], e.g. symbol_onehot:float32 (the "
        "paper's), symbol_onehot (uint8), symbol_index",
    )
    p.add_argument("--confidence", type=float, default=0.95)
    p.add_argument("--bootstrap-seed", type=int, default=0)
    p.add_argument("--no-random", action="store_true", help="skip the random-agent baseline")
    p.add_argument("--manifest-only", action="store_true", help="write the seed manifest only")
    p.add_argument("--out", type=Path, default=None, help="output folder")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument(
        "--backend",
        choices=["pool", "inprocess"],
        default="pool",
        help="pool (worker processes) or inprocess (RogueEnv games here; same results)",
    )
    return p


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Command-line entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    suite = get_suite(args.suite)
    seeds = suite.test_seed_list()
    if args.seeds_limit is not None:
        seeds = seeds[: args.seeds_limit]
    if args.manifest_only:
        rows = seed_manifest(suite, seeds)
        out = args.out or Path(f"rogue_gym_eval/{suite.name}")
        paths = write_manifest(rows, out)
        print(f"suite {suite.name} (digest {suite.digest()[:12]}), {len(rows)} test seeds")
        print(_describe_manifest(rows))
        print("wrote " + ", ".join(str(p) for p in paths))
        return 0
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    result = evaluate(
        suite,
        policy_spec=args.policy,
        episodes_per_seed=args.episodes_per_seed,
        num_envs=args.num_envs,
        num_workers=args.num_workers,
        seeds_limit=args.seeds_limit,
        obs=args.obs,
        policy_seed=args.policy_seed,
        confidence=args.confidence,
        bootstrap_seed=args.bootstrap_seed,
        with_random=not args.no_random,
        progress=not args.no_progress,
        backend=args.backend,
    )
    tag = "random" if args.policy == "random" else _safe_name(args.policy)
    out = args.out or Path(f"rogue_gym_eval/{suite.name}-{tag}")
    paths = write_results(result, out)
    print(f"suite {suite.name} (digest {suite.digest()[:12]}): {suite.description}")
    for agent in result["_agents"]:
        print(agent.line(args.confidence))
    print(f"elapsed {result['settings']['elapsed_s']:.1f} s; wrote " + ", ".join(map(str, paths)))
    return 0


def _safe_name(spec: str) -> str:
    keep = [c if c.isalnum() or c in "-_." else "_" for c in spec]
    return "".join(keep)[:60] or "policy"


if __name__ == "__main__":
    sys.exit(main())
