"""The PPO trainer (``python -m rogue_gym.train``): networks, GAE, runs, resume, determinism,
plots and the command line."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Optional

import pytest

from conftest import pid_alive

torch = pytest.importorskip("torch")

import torch.nn.functional as F  # noqa: E402
from rogue_gym.train import VARIANTS, TrainConfig, train  # noqa: E402
from rogue_gym.train.networks import MapLinear, OneHotConv2d, build_network  # noqa: E402
from rogue_gym.train.plot import plot_runs  # noqa: E402
from rogue_gym.train.ppo import compute_gae  # noqa: E402
from rogue_gym.train.progress import COLUMNS, TIMING_COLUMNS, read_progress  # noqa: E402

SYMBOLS, HEIGHT, WIDTH, ACTIONS = 17, 16, 32, 11


def smoke_config(
    out: Path, variant: str = "small", frames: int = 1024, **kw: object
) -> TrainConfig:
    """A tiny run: 8 envs x 32 steps per update, one epoch, a two-seed evaluation."""
    base: dict = dict(
        variant=variant,
        suite="paper-10",
        frames=frames,
        out=out,
        num_envs=8,
        num_workers=2,
        num_steps=32,
        epochs=1,
        minibatch_size=64,
        eval_every=512,
        eval_seeds=2,
        eval_episodes=1,
        eval_envs=2,
        random_episodes=10,
        checkpoint_every=512,
        progress=False,
        threads=1,
    )
    base.update(kw)
    return TrainConfig(**base)


def _screens(kind: str) -> torch.Tensor:
    """Symbol screens: uniform symbols, mostly blank (as in play), or a single symbol."""
    if kind == "uniform":
        return torch.randint(0, SYMBOLS, (3, HEIGHT, WIDTH), dtype=torch.uint8)
    if kind == "one":
        return torch.full((3, HEIGHT, WIDTH), 5, dtype=torch.uint8)
    x = torch.zeros((3, HEIGHT, WIDTH), dtype=torch.uint8)
    cells = torch.rand(x.shape) < 0.1
    x[cells] = torch.randint(1, 7, (int(cells.sum()),), dtype=torch.uint8)
    return x


@pytest.mark.parametrize("screens", ["uniform", "mostly_blank", "one"])
@pytest.mark.parametrize(("kernel", "padding"), [(8, 0), (3, 1), (8, 1)])
def test_one_hot_conv_equals_a_convolution_of_the_one_hot_screen(
    kernel: int, padding: int, screens: str
) -> None:
    torch.manual_seed(0)
    conv = OneHotConv2d(SYMBOLS, 12, kernel, padding=padding).double()
    x = _screens(screens)
    y = conv(x)
    grad = torch.randn_like(y)
    (y * grad).sum().backward()
    ours = (conv.weight.grad.clone(), conv.bias.grad.clone())
    conv.weight.grad = conv.bias.grad = None
    one_hot = F.one_hot(x.long(), SYMBOLS).permute(0, 3, 1, 2).double()
    ref = F.conv2d(one_hot, conv.weight, conv.bias, padding=padding)
    (ref * grad).sum().backward()
    assert y.shape == ref.shape
    torch.testing.assert_close(y, ref)
    torch.testing.assert_close(ours[0], conv.weight.grad)
    torch.testing.assert_close(ours[1], conv.bias.grad)


@pytest.mark.parametrize("channels_last", [False, True])
def test_map_linear_equals_a_linear_layer_on_the_flattened_map(channels_last: bool) -> None:
    torch.manual_seed(0)
    no_bias = MapLinear(6 * 3 * 5, 7, bias=False)
    no_bias(torch.ones(2, 6, 3, 5)).sum().backward()  # no bias, no gradient asked for it
    torch.testing.assert_close(no_bias.weight.grad, torch.full((7, 90), 2.0))
    fc = MapLinear(6 * 3 * 5, 7).double()
    h = torch.randn(4, 6, 3, 5, dtype=torch.float64)
    if channels_last:  # what a convolution hands over on a CPU
        h = h.contiguous(memory_format=torch.channels_last)
    h.requires_grad_()
    y = fc(h)
    grad = torch.randn_like(y)
    (y * grad).sum().backward()
    ours = (h.grad.clone(), fc.weight.grad.clone(), fc.bias.grad.clone())
    h.grad = fc.weight.grad = fc.bias.grad = None
    ref = F.linear(h.flatten(1), fc.weight, fc.bias)
    (ref * grad).sum().backward()
    torch.testing.assert_close(y, ref)
    for got, want in zip(ours, (h.grad, fc.weight.grad, fc.bias.grad)):
        torch.testing.assert_close(got, want)


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_variant_maps_screens_to_logits_and_values(variant: str) -> None:
    net = build_network(variant, SYMBOLS, HEIGHT, WIDTH, ACTIONS)
    x = torch.randint(0, SYMBOLS, (5, HEIGHT, WIDTH), dtype=torch.uint8)
    out = net(x, with_aux=True)
    assert out.logits.shape == (5, ACTIONS)
    assert out.value.shape == (5,)
    if variant in ("vae", "betavae"):
        assert out.aux_loss is not None and out.aux_loss.ndim == 0 and out.aux_loss.item() > 0
    else:
        assert out.aux_loss is None


def test_network_sizes_follow_the_paper() -> None:
    def params(v: str) -> int:
        return sum(
            p.numel() for p in build_network(v, SYMBOLS, HEIGHT, WIDTH, ACTIONS).parameters()
        )

    # PPO Small is about 0.74M parameters and the IMPALA ResNet about 1.15M (protocol §3.4).
    assert 0.73e6 < params("small") < 0.75e6
    assert 1.14e6 < params("large") < 1.16e6
    assert params("l2") == params("large")
    convs = [
        m
        for m in build_network("large", SYMBOLS, HEIGHT, WIDTH, ACTIONS).modules()
        if isinstance(m, (torch.nn.Conv2d, OneHotConv2d))
    ]
    assert len(convs) == 15
    bn = build_network("batchnorm", SYMBOLS, HEIGHT, WIDTH, ACTIONS)
    assert sum(isinstance(m, torch.nn.BatchNorm2d) for m in bn.modules()) == 15
    betas = {v: build_network(v, SYMBOLS, HEIGHT, WIDTH, ACTIONS).beta for v in ("vae", "betavae")}
    assert betas == {"vae": 0.0, "betavae": 4.0}


_FAULTS_SCRIPT = """
import resource, sys
import numpy as np
if sys.argv[1] == "keep":
    from rogue_gym.train.allocator import keep_freed_memory
    assert keep_freed_memory()
def rounds(n):
    for _ in range(n):  # six 10 MB blocks, then all freed: a minibatch's activations
        blocks = [np.ones(10 << 18, dtype=np.float32) for _ in range(6)]
        del blocks
rounds(3)
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
rounds(20)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_keeping_freed_memory_stops_the_page_faults_of_reallocation() -> None:
    def faults(mode: str) -> int:
        run = subprocess.run(
            [sys.executable, "-c", _FAULTS_SCRIPT, mode],
            capture_output=True,
            text=True,
            timeout=120,
            check=True,
        )
        return int(run.stdout.strip())

    plain, kept = faults("plain"), faults("keep")
    assert kept <= plain // 10, (plain, kept)


def test_gae_matches_a_hand_computed_example_and_stops_at_episode_ends() -> None:
    gamma, lam = 0.5, 0.5
    rewards = torch.tensor([[1.0], [0.0], [2.0]])
    values = torch.tensor([[0.5], [1.0], [1.0]])
    dones = torch.tensor([[0.0], [1.0], [0.0]])  # the episode ends with step 1
    last = torch.tensor([4.0])
    adv = compute_gae(rewards, values, dones, last, gamma, lam)
    d2 = 2.0 + gamma * 4.0 - 1.0  # step 2 bootstraps from the value after the rollout
    d1 = 0.0 - 1.0  # step 1 ends its episode: no bootstrap
    d0 = 1.0 + gamma * 1.0 - 0.5
    expected = [d0 + gamma * lam * d1, d1, d2]
    assert adv.squeeze(1).tolist() == pytest.approx(expected)


def _rows(out: Path) -> list[dict[str, str]]:
    return read_progress(out / "progress.csv")


def test_a_run_writes_progress_checkpoints_and_the_random_baseline(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    row = train(smoke_config(out))
    # Each evaluation's line carries the pool's health summary (its stats() since the last).
    lines = [x for x in capsys.readouterr().err.splitlines() if "generalization" in x]
    assert len(lines) == 2 and all("pool since the last line:" in x for x in lines), lines
    assert all(re.search(r"[\d,]+ steps/s \| env \d+% .*restarts 0$", x) for x in lines), lines
    rows = _rows(out)
    assert list(rows[0].keys()) == COLUMNS
    assert [int(r["frames"]) for r in rows] == [256, 512, 768, 1024]
    evals = [r for r in rows if r["gen_score"]]
    assert [int(r["frames"]) for r in evals] == [512, 1024]
    for r in evals:
        assert float(r["gen_ci_low"]) <= float(r["gen_score"]) <= float(r["gen_ci_high"])
    assert float(rows[-1]["fps"]) > 0
    assert int(rows[-1]["episodes"]) == 0  # 128 steps per env: no 500-step episode ended yet
    assert row["frames"] == 1024
    rnd = json.loads((out / "random.json").read_text())
    assert rnd["suite"] == "paper-10" and rnd["eval_seeds"] == 2
    assert rnd["train_episodes"] == 10 and rnd["train_score"] >= 0.0
    assert sorted(p.name for p in (out / "models").iterdir()) == [
        "frames-0000000512.pt",
        "frames-0000001024.pt",
    ]
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["variant"] == "small" and cfg["weight_decay"] == 0.0


def test_the_training_score_counts_finished_episodes(tmp_path: Path) -> None:
    # 8 envs x 64 steps per update: the 500-step episodes end during the 8th update.
    out = tmp_path / "run"
    train(smoke_config(out, frames=4608, num_steps=64, eval_every=0, checkpoint_every=0))
    rows = _rows(out)
    assert int(rows[6]["episodes"]) == 0 and rows[6]["train_score"] == ""
    assert int(rows[-1]["episodes"]) == 8
    assert float(rows[-1]["train_score"]) >= 0.0


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_variant_trains_and_resumes_from_its_checkpoint(tmp_path: Path, variant: str) -> None:
    out = tmp_path / variant
    train(smoke_config(out, variant, frames=512, eval_every=512, checkpoint_every=512))
    saved = torch.load(out / "checkpoint.pt", weights_only=False)
    assert saved["frames"] == 512 and saved["config"]["variant"] == variant
    net = build_network(variant, SYMBOLS, HEIGHT, WIDTH, ACTIONS)
    net.load_state_dict(saved["model"])
    train(smoke_config(out, variant, frames=1024, eval_every=512, resume=True))
    rows = _rows(out)
    assert [int(r["frames"]) for r in rows] == list(range(256, 1025, 256))
    assert int(rows[-1]["updates"]) == 4
    assert [r["frames"] for r in rows if r["gen_score"]] == ["512", "1024"]
    resumed = torch.load(out / "checkpoint.pt", weights_only=False)
    assert resumed["frames"] == 1024
    if variant == "l2":
        assert resumed["optimizer"]["param_groups"][0]["weight_decay"] == 1e-4


def test_same_seed_same_progress_csv(tmp_path: Path) -> None:
    runs = []
    for name in ("a", "b"):
        train(smoke_config(tmp_path / name, frames=768, eval_every=768, seed=3))
        runs.append(_rows(tmp_path / name))
    strip = [
        [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows] for rows in runs
    ]
    assert strip[0] == strip[1]
    other = tmp_path / "c"
    train(smoke_config(other, frames=768, eval_every=768, seed=4))
    third = [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in _rows(other)]
    assert third != strip[0]


def test_refuses_to_overwrite_a_run_and_to_resume_nothing(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        train(smoke_config(out, resume=True))
    train(smoke_config(out, frames=256, eval_every=0))
    with pytest.raises(FileExistsError, match="--resume"):
        train(smoke_config(out, frames=256))
    with pytest.raises(ValueError, match="already has 256 frames"):
        train(smoke_config(out, frames=256, resume=True))
    with pytest.raises(ValueError, match="variant='small'"):
        train(smoke_config(out, variant="large", frames=512, resume=True))
    with pytest.raises(ValueError, match="variant"):
        train(smoke_config(tmp_path / "x", variant="huge"))
    with pytest.raises(ValueError, match="minibatch_size"):
        train(smoke_config(tmp_path / "y", minibatch_size=10_000))


def test_plot_draws_runs_and_the_random_line(tmp_path: Path) -> None:
    # One run, trained, and a copy of it: a run is named by its folder or by its progress.csv.
    run = tmp_path / "small"
    train(smoke_config(run, "small", frames=512, eval_every=256))
    copy = tmp_path / "again"
    shutil.copytree(run, copy)
    png = plot_runs([run, copy / "progress.csv"], tmp_path / "fig" / "curves.png")
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_command_line_trains_and_reports_bad_flags(tmp_path: Path) -> None:
    out = tmp_path / "cli"
    cmd = [sys.executable, "-m", "rogue_gym.train", "--variant", "small", "--suite", "paper-10"]
    small = ["--num-envs", "8", "--num-steps", "32", "--epochs", "1", "--minibatch-size", "64"]
    small += ["--eval-seeds", "2", "--eval-episodes", "1", "--eval-envs", "2", "--no-progress"]
    small += ["--random-episodes", "10"]
    done = subprocess.run(
        [*cmd, "--frames", "256", "--seed", "1", "--out", str(out), *small],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert done.returncode == 0, done.stderr
    assert "done: 256 frames" in done.stdout
    with (out / "progress.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 1
    again = subprocess.run(
        [*cmd, "--frames", "256", "--out", str(out), *small],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert again.returncode == 2 and "--resume" in again.stderr
    bad = subprocess.run([*cmd, "--variant", "huge"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "invalid choice" in bad.stderr
    plot = subprocess.run(
        [sys.executable, "-m", "rogue_gym.train.plot", str(out), "--out", str(tmp_path / "c.png")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert plot.returncode == 0, plot.stderr
    assert (tmp_path / "c.png").stat().st_size > 0


def _collect(num_workers: int, seed: int) -> tuple:
    """One rollout of 8 envs x 32 steps by a fresh network, through a pool of ``num_workers``."""
    from rogue_gym.train.rollout import Collector, Rollout
    from rogue_gym.train.trainer import _make_pool

    cfg = smoke_config(Path("unused"), num_workers=num_workers).checked()
    env = _make_pool(cfg, seed=seed)
    try:
        torch.manual_seed(0)
        net = build_network("small", SYMBOLS, HEIGHT, WIDTH, ACTIONS)
        collector = Collector(env, cfg.num_steps, torch.device("cpu"), seed=seed)
        buf = Rollout.empty(cfg.num_steps, cfg.num_envs, (HEIGHT, WIDTH), torch.device("cpu"))
        collector.collect(net, buf)
        groups = len(collector._groups)
    finally:
        env.close()
    return buf, groups


def test_collection_overlaps_worker_groups_and_is_independent_of_the_layout() -> None:
    two, groups_two = _collect(num_workers=2, seed=5)
    four, groups_four = _collect(num_workers=4, seed=5)
    assert (groups_two, groups_four) == (2, 4)  # one send/recv group per worker
    assert two.obs.shape == (32, 8, HEIGHT, WIDTH) and two.obs.dtype == torch.uint8
    assert int(two.obs.max()) > 0 and int(two.actions.max()) < ACTIONS
    # The same envs, levels and sampling noise: the same actions and screens for any layout.
    assert torch.equal(two.actions, four.actions)
    assert torch.equal(two.obs, four.obs)
    torch.testing.assert_close(two.values, four.values)
    other, _ = _collect(num_workers=2, seed=6)
    assert not torch.equal(two.actions, other.actions)


def _workers(pid: int) -> dict[int, str]:
    """The pool workers among process ``pid``'s children: pid -> command line."""
    import glob

    found = {}
    for path in glob.glob(f"/proc/{pid}/task/*/children"):
        try:
            with open(path) as f:
                kids = [int(p) for p in f.read().split()]
        except FileNotFoundError:
            continue
        for kid in kids:
            try:
                with open(f"/proc/{kid}/cmdline") as f:
                    cmd = f.read().replace("\0", " ")
            except FileNotFoundError:
                continue
            if "rogue_gym.worker" in cmd:
                found[kid] = cmd
    return found


def _start_cli_run(
    out: Path, frames: int, *extra: str, env: Optional[dict[str, str]] = None
) -> subprocess.Popen:
    """A tiny CLI training run (8 envs x 32 steps, one epoch) in a child process."""
    args = [sys.executable, "-m", "rogue_gym.train", "--frames", str(frames), "--out", str(out)]
    args += ["--num-envs", "8", "--num-steps", "32", "--epochs", "1", "--minibatch-size", "64"]
    args += ["--eval-seeds", "2", "--eval-episodes", "1", "--eval-envs", "2"]
    args += ["--random-episodes", "10", "--threads", "1", "--no-progress", *extra]
    return subprocess.Popen(
        args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )


def _wait_for_rows(proc: subprocess.Popen, out: Path, rows: int, timeout: float = 180) -> None:
    """Wait (bounded) until the run has written ``rows`` rows of ``progress.csv``: its random
    baseline is done and its workers are the training pool's."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "progress.csv").exists() and len(_rows(out)) >= rows:
            return
        time.sleep(0.2)


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.wait(timeout=30)


def test_training_survives_a_killed_worker(tmp_path: Path) -> None:
    import os
    import signal
    import time

    out = tmp_path / "run"
    proc = _start_cli_run(out, 4096, "--eval-every", "0")
    try:
        _wait_for_rows(proc, out, 2)
        workers = _workers(proc.pid)
        victim = next((p for p, cmd in workers.items() if "--index 0 " in cmd), None)
        assert victim is not None, f"no worker 0 among {workers}"
        os.kill(victim, signal.SIGKILL)
        # The pool notices the death when it next waits on that worker and starts generation 1.
        respawned = False
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None and not respawned:
            respawned = any("--generation 1 " in c for c in _workers(proc.pid).values())
            time.sleep(0.1)
        stdout, stderr = proc.communicate(timeout=240)
    finally:
        _stop(proc)
    assert proc.returncode == 0, stderr[-2000:]
    assert "done: 4096 frames" in stdout
    rows = _rows(out)
    assert int(rows[-1]["frames"]) == 4096
    # The killed worker's 4 envs were rebuilt and their episodes cut short, once.
    restarted = [int(r["restarted_envs"]) for r in rows]
    assert restarted[0] == 0 and restarted[-1] == 4, (respawned, restarted, stderr[-2000:])


def test_sigterm_stops_training_and_leaves_nothing_behind(tmp_path: Path) -> None:
    import os
    import signal
    import tempfile
    import time

    # The run's pools live in a runtime directory of its own, so that its files are told from
    # those of other pools on the machine (/dev/shm is shared). Short: iceoryx2's socket paths
    # are limited.
    short = tempfile.TemporaryDirectory(prefix="rgt", dir="/tmp")
    runtime = Path(short.name) / "rt"
    out = tmp_path / "run"
    proc = _start_cli_run(out, 100000, env={**os.environ, "ROGUE_GYM_RUNTIME_DIR": str(runtime)})
    try:
        _wait_for_rows(proc, out, 1)
        workers = _workers(proc.pid)
        assert workers, "no training workers"
        pools = {entry.name.split(".")[0] for entry in runtime.iterdir()}
        assert pools, "the run's pools are not in its runtime directory"
        proc.send_signal(signal.SIGTERM)
        _, stderr = proc.communicate(timeout=120)
    finally:
        _stop(proc)
    assert proc.returncode == 130, stderr[-2000:]
    assert "--resume" in stderr
    time.sleep(0.5)
    for pid in workers:
        assert not pid_alive(pid), f"worker {pid} outlived the trainer"
    leaked = [f for f in os.listdir("/dev/shm") if f.split("_")[0] in pools]
    assert not leaked, f"left in /dev/shm: {sorted(leaked)[:5]}"
    assert not list(runtime.iterdir()), "left in the runtime directory"
    short.cleanup()


def test_saved_checkpoints_are_rescored_post_hoc_as_in_training_and_resume(tmp_path: Path) -> None:
    from rogue_gym.evaluate import evaluate
    from rogue_gym.suites import get_suite
    from rogue_gym.train.posthoc import checkpoint_policy, score_runs

    out = tmp_path / "run"
    train(smoke_config(out))
    in_training = {int(r["frames"]): float(r["gen_score"]) for r in _rows(out) if r["gen_score"]}
    logged: list[str] = []
    # The in-training protocol (2 seeds x 1 episode, 2 envs, the run's seed): the same scores.
    files = score_runs([out], 2, 1, num_envs=2, num_workers=2, seed=0, log=logged.append)
    with files[out].open() as f:
        rows = list(csv.DictReader(f))
    assert {int(r["frames"]): float(r["gen_score"]) for r in rows} == in_training
    assert files[out].name == "posthoc-2-1.csv"
    # Scored checkpoints are skipped: the scoring resumes where it stopped.
    score_runs([out], 2, 1, num_envs=2, num_workers=2, seed=0, log=logged.append)
    assert logged[-1].endswith("2 scored, 0 to score")
    # The evaluator takes a checkpoint as a policy (symbol indices whatever --obs says).
    policy = checkpoint_policy(out / "models" / "frames-0000001024.pt")
    assert policy.config.variant == "small" and policy.required_obs == "symbol_index"
    res = evaluate(
        get_suite("paper-10"),
        policy_spec=f"checkpoint:{out / 'models' / 'frames-0000001024.pt'}",
        seeds_limit=2,
        episodes_per_seed=1,
        num_envs=2,
        with_random=False,
        progress=False,
    )
    assert res["_agents"][0].returns.shape == (2, 1)
    with pytest.raises(ValueError, match=r"frames-N\.pt"):
        checkpoint_policy(out / "config.json")


def test_compat_original_initialises_as_the_papers_code() -> None:
    gain2 = 2.0  # orthogonal rows of norm sqrt(2)
    for variant in ("small", "large", "vae"):
        ours = build_network(variant, SYMBOLS, HEIGHT, WIDTH, ACTIONS)
        orig = build_network(variant, SYMBOLS, HEIGHT, WIDTH, ACTIONS, original=True)
        assert float(ours.value_head.weight.detach().pow(2).sum()) == pytest.approx(1.0, rel=1e-5)
        assert float(orig.value_head.weight.detach().pow(2).sum()) == pytest.approx(gain2, rel=1e-5)
        assert sum(p.numel() for p in ours.parameters()) >= sum(
            p.numel() for p in orig.parameters()
        )
    large = build_network("large", SYMBOLS, HEIGHT, WIDTH, ACTIONS, original=True)
    residual_biases = [m.bias for m in large.modules() if isinstance(m, torch.nn.Conv2d)]
    assert residual_biases and all(b is None for b in residual_biases), "no conv biases"
    vae = build_network("vae", SYMBOLS, HEIGHT, WIDTH, ACTIONS, original=True)
    for layer in (vae.mu, vae.logvar, vae.dec_fc1):
        w = layer.weight.detach()
        rows = w @ w.T if w.shape[0] <= w.shape[1] else w.T @ w
        assert torch.allclose(rows, gain2 * torch.eye(rows.shape[0]), atol=1e-4)


def test_compat_original_keeps_batchnorm_in_train_mode_and_evaluates_same_seed_batches(
    tmp_path: Path,
) -> None:
    from rogue_gym.suites import get_suite
    from rogue_gym.train.evaluation import generalization, same_seed_schedule
    from rogue_gym.train.posthoc import load_network

    assert same_seed_schedule([5, 7], 3) == [5, 5, 5, 7, 7, 7]
    net = build_network("batchnorm", SYMBOLS, HEIGHT, WIDTH, ACTIONS)
    bn = next(m for m in net.modules() if isinstance(m, torch.nn.BatchNorm2d))
    seen: list[tuple[bool, int]] = []
    bn.register_forward_pre_hook(lambda m, x: seen.append((m.training, x[0].shape[0])))
    suite = get_suite("paper-10")
    for compat, mode in (("ours", False), ("original", True)):
        seen.clear()
        net.train(True)
        generalization(net, torch.device("cpu"), suite, 2, 2, 4, 2, 0, compat)
        assert {m for m, _ in seen} == {mode}, compat
        assert net.training, "the caller's mode is restored"
    assert {b for _, b in seen} == {2}, "original: one batch of the seed's 2 episodes"
    # A whole run under --compat original: minibatch 400 by default, the BN variant trains,
    # and its checkpoint loads (same architecture) in train mode.
    cfg = smoke_config(tmp_path / "orig", "batchnorm", frames=512, compat="original")
    cfg = dataclasses.replace(cfg, minibatch_size=None, num_steps=64)
    assert cfg.checked().minibatch_size == 400
    train(cfg)
    saved = json.loads((tmp_path / "orig" / "config.json").read_text())
    assert saved["compat"] == "original" and saved["minibatch_size"] == 400
    loaded, _ = load_network(tmp_path / "orig" / "models" / "frames-0000000512.pt")
    assert loaded.training


def test_the_paper_matrix_prints_runs_and_resumably_trains_and_scores(tmp_path: Path) -> None:
    from rogue_gym.train import matrix

    assert [r.name for r in matrix.runs()] == [
        "small-10",
        "large-10",
        "batchnorm-10",
        "l2-10",
        "vae-10",
        "betavae-10",
        "large-20",
        "l2-20",
        "betavae-20",
        "large-40",
        "l2-40",
        "betavae-40",
    ]
    with pytest.raises(ValueError, match="unknown runs"):
        matrix.runs(["small-7"])
    out = tmp_path / "paper"
    smoke = "--num-envs 8 --num-steps 32 --epochs 1 --minibatch-size 64 --eval-envs 2 "
    smoke += "--random-episodes 10 --no-progress --threads 1"
    argv = ["--only", "small-10", "--out", str(out), "--device", "cpu", "--frames", "512"]
    argv += ["--checkpoint-every", "256", "--eval-seeds", "2", "--eval-episodes", "1"]
    argv += ["--run", "--", *smoke.split()]
    assert matrix.main(argv) == 0
    run = out / "small-10"
    cfg = json.loads((run / "config.json").read_text())
    assert (cfg["suite"], cfg["frames"], cfg["compat"]) == ("paper-10-original", 512, "ours")
    with (run / "posthoc-2-1.csv").open() as f:
        assert [int(r["frames"]) for r in csv.DictReader(f)] == [256, 512]
    meta = json.loads((out / "matrix.json").read_text())
    assert meta["runs"] == ["small-10"] and meta["protocol"]["eval_seeds"] == 2
    # Done: only the (resumable, here empty) scoring and the evaluation are left.
    args = matrix.parser().parse_args(argv)
    due = matrix.commands(matrix.runs(["small-10"])[0], args)
    assert len(due) == 2 and "rogue_gym.train.posthoc" in due[0]
    assert "rogue_gym.evaluate" in due[1] and f"checkpoint:{run}" in due[1]
    # The paper's table: train and test scores and the gap, from the run's evaluation.
    (row,) = matrix.report([out])
    assert (row["variant"], row["suite"], row["runs"]) == ("small", "paper-10-original", 1)
    doc = json.loads((run / "eval" / "summary.json").read_text())
    assert row["test"][0] == doc["agents"][0]["mean"]
    assert row["train"][0] == doc["train_agents"][0]["mean"]
    assert row["gap"][0] == pytest.approx(row["train"][0] - row["test"][0])
    assert row["normalized_test"] is not None
    assert matrix.main(["--report", str(out)]) == 0
    # The paper's analyses on the same run, and the figures the plot command draws of them.
    from rogue_gym.train.plot import plot_runs
    from rogue_gym.train.posthoc import entropy_runs, one_seed_runs

    ent = entropy_runs([run], seeds=2, episodes=2, log=lambda _: None)[run]
    with ent.open() as f:
        rows = list(csv.DictReader(f))
    assert [int(r["frames"]) for r in rows] == [256, 512]
    assert all(0.0 < float(r["entropy"]) <= math.log(11) + 1e-6 for r in rows)
    seed = json.loads(one_seed_runs([run], 1008, trials=2, log=lambda _: None)[run].read_text())
    assert seed["seed"] == 1008 and len(seed["returns"]) == 2 and seed["frames"] == 512
    assert sum(seed["action_probs"].values()) == pytest.approx(1.0, abs=1e-4)
    png = plot_runs([run], tmp_path / "fig.png")
    assert png.exists() and (tmp_path / "fig-seed.png").exists()
    assert "small-10" in (tmp_path / "fig-seed.md").read_text()
