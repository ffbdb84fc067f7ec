"""The training loop: collect a rollout, update, log, evaluate, checkpoint; repeat.

Read top to bottom, :func:`train` is the whole algorithm; each step lives in its own module
(:mod:`.rollout`, :mod:`.ppo`, :mod:`.evaluation`, :mod:`.progress`, :mod:`.checkpoint`).
"""

from __future__ import annotations

import json
import time
from typing import Any, Dict, Optional

import torch

from ..suite_pool import suite_pool
from ..suites import get_suite
from .allocator import keep_freed_memory
from .checkpoint import CHECKPOINT, load, save
from .config import TrainConfig
from .evaluation import generalization, random_baseline
from .networks import build_network
from .ppo import ppo_update
from .progress import ProgressLog, truncate_after
from .rollout import Collector, Rollout

__all__ = ["train"]


def _make_pool(cfg: TrainConfig, seed: int) -> Any:
    """The training pool: the suite's training seeds, symbol indices, one worker per batch."""
    suite = get_suite(cfg.suite)
    return suite_pool(
        suite,
        cfg.num_envs,
        num_workers=cfg.num_workers,
        seeds=suite.train_seed_list(),
        seed_policy="sample",
        seed=seed,
        obs="symbol_index",
        batch_size=cfg.num_envs // cfg.num_workers,
    )


def _adam(net: torch.nn.Module, cfg: TrainConfig) -> torch.optim.Adam:
    """The paper's Adam; the fused kernel (one pass per tensor) where this torch has it."""
    params = list(net.parameters())
    kw: Dict[str, Any] = dict(lr=cfg.lr, eps=cfg.adam_eps, weight_decay=cfg.weight_decay or 0.0)
    try:
        return torch.optim.Adam(params, fused=True, **kw)
    except (RuntimeError, TypeError):  # an older torch, or a device without the fused kernel
        return torch.optim.Adam(params, **kw)


def _due(before: int, after: int, every: int) -> bool:
    """Whether a multiple of ``every`` lies in ``(before, after]``."""
    return every > 0 and after // every > before // every


def train(cfg: TrainConfig) -> Dict[str, Any]:
    """Train one agent as ``cfg`` says; returns the last ``progress.csv`` row."""
    cfg = cfg.checked()
    out = cfg.out
    out.mkdir(parents=True, exist_ok=True)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    keep_freed_memory()  # the update loop reuses its blocks instead of faulting them in
    device = torch.device(cfg.device)
    suite = get_suite(cfg.suite)
    torch.manual_seed(cfg.seed)

    state: Optional[Dict[str, Any]] = None
    if cfg.resume:
        state = load(out)
        saved = state["config"]
        for key in ("variant", "suite", "num_envs", "num_steps", "compat"):
            if saved.get(key, "ours" if key == "compat" else None) != getattr(cfg, key):
                raise ValueError(
                    f"--resume: the run in {out} has {key}={saved[key]!r}, not "
                    f"{getattr(cfg, key)!r}; resume with the same {key}"
                )
        if int(state["frames"]) >= cfg.frames:
            raise ValueError(
                f"--resume: the run in {out} already has {state['frames']} frames; pass a "
                "larger --frames to continue it"
            )
    elif (out / CHECKPOINT).exists() or (out / "progress.csv").exists():
        raise FileExistsError(
            f"{out} already holds a run; pass --resume to continue it or choose another --out"
        )
    cfg.save(out / "config.json")

    # The random agent on the same seeds, once per run folder (the plots' reference line).
    random_path = out / "random.json"
    if not random_path.exists():
        rnd = random_baseline(
            suite,
            cfg.eval_seeds,
            cfg.eval_episodes,
            cfg.eval_envs,
            cfg.num_workers,
            cfg.random_episodes,
        )
        random_path.write_text(json.dumps(rnd, indent=1) + "\n")

    updates = 0 if state is None else int(state["updates"])
    # A resumed run restarts its envs: a fresh episode schedule, not a replay of the first.
    env = _make_pool(cfg, seed=cfg.seed * 1_000_003 + updates)
    try:
        space = env.single_observation_space  # symbol indices: Box(0, symbols - 1, (H, W))
        obs_shape = tuple(space.shape)
        symbols = int(space.high.max()) + 1
        original = cfg.compat == "original"
        net = build_network(
            cfg.variant,
            symbols,
            obs_shape[0],
            obs_shape[1],
            int(env.single_action_space.n),
            original=original,
        ).to(device)
        optimizer = _adam(net, cfg)
        collector = Collector(env, cfg.num_steps, device, seed=cfg.seed)
        update_gen = torch.Generator(device="cpu")
        update_gen.manual_seed(cfg.seed + 1)
        frames = 0
        if state is not None:
            net.load_state_dict(state["model"])
            optimizer.load_state_dict(state["optimizer"])
            collector.stats.load_state_dict(state["episodes"])
            collector.restarted_envs = int(state.get("restarted_envs", 0))
            collector.generator.set_state(state["collector_rng"])
            update_gen.set_state(state["update_rng"])
            torch.set_rng_state(state["torch_rng"])
            frames = int(state["frames"])
            truncate_after(out / "progress.csv", frames)
        buf = Rollout.empty(cfg.num_steps, cfg.num_envs, obs_shape, device)
        log = ProgressLog(out / "progress.csv", cfg.frames, frames, cfg.progress)
        update_s = eval_s = 0.0
        row: Dict[str, Any] = {}
        try:
            while frames < cfg.frames:
                t0 = time.perf_counter()
                collector.collect(net, buf, train_mode=original)
                t1 = time.perf_counter()
                stats = ppo_update(net, optimizer, buf, cfg, update_gen)
                t2 = time.perf_counter()
                update_s += t2 - t1
                before, frames, updates = frames, frames + cfg.batch_size, updates + 1
                row = {
                    "frames": frames,
                    "updates": updates,
                    "episodes": collector.stats.episodes,
                    "restarted_envs": collector.restarted_envs,
                    "train_score": collector.stats.score(),
                    "fps": cfg.batch_size / (t2 - t0),
                    **stats.as_dict(),
                }
                last = frames >= cfg.frames
                if last or _due(before, frames, cfg.eval_every):
                    t3 = time.perf_counter()
                    gen = generalization(
                        net,
                        device,
                        suite,
                        cfg.eval_seeds,
                        cfg.eval_episodes,
                        cfg.eval_envs,
                        cfg.num_workers,
                        cfg.seed,
                        cfg.compat,
                    )
                    eval_s += time.perf_counter() - t3
                    row.update(gen_score=gen.mean, gen_ci_low=gen.ci_low, gen_ci_high=gen.ci_high)
                    log.message(
                        f"frames {frames}: train {row['train_score']:.2f}, "
                        f"generalization {gen.mean:.2f} [{gen.ci_low:.2f}, {gen.ci_high:.2f}]; "
                        f"pool since the last line: {env.stats(reset=True)}"
                    )
                row.update(
                    env_s=collector.env_seconds,
                    policy_s=collector.policy_seconds,
                    update_s=update_s,
                    eval_s=eval_s,
                )
                log.row(row, cfg.batch_size)
                if last or _due(before, frames, cfg.checkpoint_every):
                    save(
                        out,
                        {
                            "config": cfg.to_json(),
                            "frames": frames,
                            "updates": updates,
                            "model": net.state_dict(),
                            "optimizer": optimizer.state_dict(),
                            "episodes": collector.stats.state_dict(),
                            "restarted_envs": collector.restarted_envs,
                            "collector_rng": collector.generator.get_state(),
                            "update_rng": update_gen.get_state(),
                            "torch_rng": torch.get_rng_state(),
                        },
                    )
        finally:
            log.close()
    finally:
        env.close()
    return row
