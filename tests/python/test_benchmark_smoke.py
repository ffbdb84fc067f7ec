"""The throughput benchmark runs end to end in its short mode (no timing is asserted)."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "vecenv_throughput.py"
BACKENDS = ["pool-sync", "pool-async", "gym-sync", "gym-async-shm", "sb3-dummy", "sb3-subproc"]


def test_short_benchmark_writes_table_and_plot(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("matplotlib")
    cmd = [
        sys.executable,
        str(SCRIPT),
        "--short",
        "--num-envs",
        "8",
        "--obs",
        "symbol_index",
        "--reps",
        "1",
        "--seconds",
        "0.3",
        "--out",
        str(tmp_path),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    md = (tmp_path / "throughput.md").read_text()
    png = tmp_path / "throughput.png"
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"
    doc = json.loads((tmp_path / "throughput.json").read_text())
    rows = {r["backend"]: r for r in doc["runs"]}
    assert set(rows) == set(BACKENDS)
    for backend in BACKENDS:
        assert f"| 8 | {backend} |" in md, backend
        # Every backend must actually run on this tiny cell (no error, no skip).
        assert rows[backend]["status"] == "ok", rows[backend]
        assert rows[backend]["steps_per_s"] > 0
    assert "ratio pool-sync / gym-async-shm" in md
    # The table and plot can be re-rendered from the saved JSON alone.
    again = tmp_path / "again"
    cmd = [sys.executable, str(SCRIPT), "--from-json", str(tmp_path / "throughput.json")]
    subprocess.run([*cmd, "--out", str(again)], check=True, capture_output=True, timeout=120)
    assert (again / "throughput.md").read_text() == md
    assert (again / "throughput.png").stat().st_size > 1000


def test_a_cell_past_its_time_limit_is_skipped_not_hung(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("matplotlib")
    cmd = [
        sys.executable,
        str(SCRIPT),
        "--backends",
        "sb3-subproc",
        "--num-envs",
        "8",
        "--obs",
        "symbol_index",
        "--reps",
        "2",
        "--cell-timeout",
        "0.5",
        "--out",
        str(tmp_path),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    runs = json.loads((tmp_path / "throughput.json").read_text())["runs"]
    assert [r["status"] for r in runs] == ["skipped", "skipped"]  # not retried in rep 2
    assert "**skipped**" in (tmp_path / "throughput.md").read_text()


def test_the_device_script_runs_every_part_in_its_quick_mode(tmp_path: Path) -> None:
    """``benchmarks/device.sh --quick``: scaling and its model, the async head-to-head (this
    pool beside TorchRL where installed) and the trainer, each writing its results."""
    env = {**__import__("os").environ, "PYTHON": sys.executable, "DEVICE_OUT": str(tmp_path)}
    proc = subprocess.run(
        ["bash", str(ROOT / "benchmarks" / "device.sh"), "--quick"],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    scaling = json.loads((tmp_path / "scaling.json").read_text())
    assert all(v[0] > 0 for t in scaling["runs"].values() for v in t.values())
    # The model: the caller's own time, the worker's env time, and of the own time the
    # worker's idle time and the caller's time between calls, for each batch size; and the
    # efficiency it projects (a fraction) for the native game at 1 to 16 workers.
    model = json.loads((tmp_path / "model.json").read_text())
    assert all(
        o >= 0 and t > 0 and idle >= 0 and between >= 0
        for cells in model["cells"].values()
        for o, t, idle, between in cells
    )
    assert 0 < model["projected"]["rogue/16"] < 1
    # Its control: every batch but the smallest measured again as the smallest batch after
    # an equally long wait, and the projection at one worker's wait.
    assert model["controls"].keys() == {
        k for k in model["cells"] if k not in ("rogue/16", "CartPole-v1/2")
    }
    assert all(
        o >= 0 and between >= 0 for c in model["controls"].values() for o, _, _, between in c
    )
    assert 0 < model["projected_at_t_w"]["rogue/16"] < 1
    pools = json.loads((tmp_path / "async_pools.json").read_text())
    # The machine's hand-off beside the figures: on one core, and across two where it has two.
    cores = len(os.sched_getaffinity(0))
    assert pools["handoff_us"].keys() == ({"one core", "two cores"} if cores > 1 else {"one core"})
    assert all(v > 0 for v in pools["handoff_us"].values())
    rows = pools["runs"]["dispatch"]
    assert any(k.startswith("rogue_gym async") and v and v[0] > 0 for k, v in rows.items())
    if __import__("importlib").util.find_spec("torchrl") is not None:
        assert any(k.startswith("torchrl") and v and v[0] > 0 for k, v in rows.items()), rows
    train = json.loads((tmp_path / "train.json").read_text())
    assert train["fps_last"] > 0 and train["updates"] >= 1


def test_the_multi_agent_benchmark_puts_every_system_side_by_side(tmp_path: Path) -> None:
    """``benchmarks/multi_agent.py --quick``: the pool, SuperSuit (where installed) and the
    plain loop each give a figure, and the table their ratios."""
    pytest.importorskip("mpe2")
    script = str(ROOT / "benchmarks" / "multi_agent.py")
    proc = subprocess.run(
        [sys.executable, script, "--quick", "--envs", "simple_spread", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    runs = json.loads((tmp_path / "multi_agent.json").read_text())["results"]["simple_spread x 8"]
    assert runs["pool"][0] > 0 and runs["plain_loop"][0] > 0
    if importlib.util.find_spec("supersuit") is not None:
        assert runs["supersuit_1p"][0] > 0
    assert "pool / plain loop" in (tmp_path / "multi_agent.md").read_text()
