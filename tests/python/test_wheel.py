"""The binary wheel: built once by ``scripts/build-wheel.sh``, installed into a fresh venv with no
cargo on PATH, and used there as a user would (the pool, its workers, one game, the evaluator).

Building links the extension anew with zig (a few minutes), so this module has its own time
limit. ``scripts/test.sh`` builds it beside the type checks, before pytest (failing loudly if
the build fails), and names the directory that holds it in ``ROGUE_GYM_WHEEL_DIR``; without it
the module builds the wheel itself. Set ``ROGUE_GYM_SKIP_WHEEL=1`` to skip it in a quick local
run.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Optional

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = [
    pytest.mark.timeout(1500),
    pytest.mark.skipif(
        os.environ.get("ROGUE_GYM_SKIP_WHEEL") == "1", reason="ROGUE_GYM_SKIP_WHEEL=1"
    ),
]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    built = os.environ.get("ROGUE_GYM_WHEEL_DIR")
    if built:
        out = Path(built)
    else:
        out = tmp_path_factory.mktemp("wheels")
        proc = subprocess.run(
            ["bash", str(ROOT / "scripts" / "build-wheel.sh"), str(out)],
            capture_output=True,
            text=True,
            timeout=1200,
        )
        assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    wheels = list(out.glob("rogue_gym-*.whl"))
    assert len(wheels) == 1, wheels
    return wheels[0]


@pytest.fixture(scope="module")
def venv(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A fresh venv with the wheel installed (its dependencies from the package index)."""
    root = tmp_path_factory.mktemp("venv")
    subprocess.run([sys.executable, "-m", "venv", str(root)], check=True, timeout=120)
    py = root / "bin" / "python"
    proc = subprocess.run(
        [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check", str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
        env=_clean_env(root),
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    yield root
    shutil.rmtree(root, ignore_errors=True)


def _clean_env(venv: Path) -> dict[str, str]:
    """The environment of a user without Rust: the venv and the system dirs on PATH only."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("CARGO", "RUST", "PYTHON"))}
    env["PATH"] = os.pathsep.join([str(venv / "bin"), "/usr/local/bin", "/usr/bin", "/bin"])
    env.pop("VIRTUAL_ENV", None)
    return env


def test_the_wheel_is_abi3_manylinux_and_holds_only_the_package(wheel: Path) -> None:
    assert wheel.name.startswith("rogue_gym-")
    assert "-cp39-abi3-" in wheel.name and "manylinux_2_17_x86_64" in wheel.name
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
        wheel_file = z.read(next(n for n in names if n.endswith(".dist-info/WHEEL"))).decode()
        metadata = z.read(meta).decode()
    assert "Tag: cp39-abi3-manylinux_2_17_x86_64" in wheel_file
    assert "Root-Is-Purelib: false" in wheel_file
    assert "rogue_gym/_native.abi3.so" in names and "rogue_gym/py.typed" in names
    for n in names:
        assert n.startswith(("rogue_gym/", "rogue_gym-")), n
        assert not n.endswith((".rs", "Cargo.toml", "Cargo.lock")), n
        assert "/tests/" not in n and not Path(n).name.startswith("test_"), n
    assert "Requires-Python: >=3.9" in metadata
    assert "License-Expression: MIT" in metadata or "License: MIT" in metadata
    assert "Provides-Extra: sb3" in metadata


def test_the_installed_wheel_runs_without_rust(venv: Path, tmp_path: Path) -> None:
    env = _clean_env(venv)
    assert shutil.which("cargo", path=env["PATH"]) is None
    script = textwrap.dedent(
        """
        import sys
        import numpy as np
        import rogue_gym
        from rogue_gym.envs import RogueEnv

        assert rogue_gym.__file__.startswith(sys.prefix), rogue_gym.__file__
        envs = rogue_gym.make_vec(4, num_workers=2, seed=0)
        try:
            obs, _ = envs.reset(seed=0)
            assert obs.shape == (4, 17, 16, 32)
            for _ in range(20):
                obs, rew, term, trunc, infos = envs.step(np.zeros(4, np.int64))
            # The workers run the installed package's extension.
            for pid in envs.worker_pids:
                with open(f"/proc/{pid}/cmdline", "rb") as f:
                    argv = f.read().split(b"\\0")
                assert argv[0].decode() == sys.executable and b"rogue_gym.worker" in argv, argv
        finally:
            envs.close()
        env = RogueEnv(config_dict=rogue_gym.PAPER_CONFIG, max_steps=30)
        env.reset(seed=1)
        steps = 0
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(env.action_space.sample())
            done = term or trunc
            steps += 1
        assert steps == 30
        print("ok", rogue_gym.__version__)
        """
    )
    py = str(venv / "bin" / "python")
    r = subprocess.run(
        [py, "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.startswith("ok ")
    h = subprocess.run(
        [py, "-m", "rogue_gym.evaluate", "--help"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert h.returncode == 0 and "--suite" in h.stdout, h.stdout + h.stderr


def _python(version: str) -> Optional[str]:
    """An interpreter of ``version`` (``"3.9"``) on this machine: pyenv's, else on PATH."""
    pyenv = Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv")) / "versions"
    for root in sorted(pyenv.glob(f"{version}.*"), reverse=True):
        exe = root / "bin" / f"python{version}"
        if exe.exists():
            return str(exe)
    found = shutil.which(f"python{version}")
    if found:
        probe = subprocess.run([found, "--version"], capture_output=True, text=True, timeout=60)
        if probe.returncode == 0:
            return found
    return None


def _declared(wheel: Path) -> tuple[str, list[str]]:
    """The wheel's oldest Python and its dependencies pinned to their declared floors
    (``numpy>=1.24`` becomes ``numpy==1.24``), from its own metadata."""
    with zipfile.ZipFile(wheel) as z:
        meta = z.read(next(n for n in z.namelist() if n.endswith(".dist-info/METADATA")))
    python, pins = "", []
    for line in meta.decode().splitlines():
        if line.startswith("Requires-Python:"):
            python = line.split(">=")[1].strip()
        elif line.startswith("Requires-Dist:") and "extra ==" not in line:
            spec = line.split(":", 1)[1].strip()
            name, rest = spec.split(">=", 1)
            pins.append(f"{name.strip()}=={rest.split(',')[0].strip()}")
    return python, pins


#: Both kinds stepped with the installed wheel: the native game and a hosted gymnasium env.
_BOTH_KINDS = textwrap.dedent(
    """
    import gymnasium as gym, numpy as np, rogue_gym
    for envs in (
        rogue_gym.make_vec(4, num_workers=2, seed=0),
        rogue_gym.PoolVectorEnv([lambda: gym.make("CartPole-v1")] * 4, num_workers=2),
    ):
        try:
            envs.reset(seed=0)
            for _ in range(10):
                envs.step(envs.action_space.sample())
        finally:
            envs.close()
    print("ok", np.__version__, gym.__version__)
    """
)


@pytest.mark.parametrize("end", ["oldest", "newest"])
def test_the_wheel_works_at_both_ends_of_its_declared_ranges(
    end: str, wheel: Path, tmp_path: Path
) -> None:
    """The oldest declared Python with the declared floor of every dependency, and Python 3.13
    with the newest of each: both kinds step."""
    oldest_python, floors = _declared(wheel)
    version = oldest_python if end == "oldest" else "3.13"
    exe = _python(version)
    if exe is None:
        pytest.skip(f"no Python {version} on this machine (pyenv or PATH)")
    root = tmp_path / f"venv-{end}"
    subprocess.run([exe, "-m", "venv", str(root)], check=True, timeout=120)
    env = _clean_env(root)
    deps = floors if end == "oldest" else ["--upgrade", *(p.split("==")[0] for p in floors)]
    pip = [str(root / "bin" / "python"), "-m", "pip", "install", "-q"]
    install = subprocess.run(
        [*pip, "--disable-pip-version-check", str(wheel), *deps],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    assert install.returncode == 0, install.stdout[-3000:] + install.stderr[-3000:]
    r = subprocess.run(
        [str(root / "bin" / "python"), "-c", _BOTH_KINDS],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.startswith("ok "), r.stdout
    if end == "oldest":
        # The floors themselves ran: "numpy==1.24" installs 1.24.0.
        pinned = dict(p.split("==") for p in floors)
        numpy_version, gym_version = r.stdout.split()[1:3]
        assert numpy_version.startswith(pinned["numpy"]), (numpy_version, pinned)
        assert gym_version.startswith(pinned["gymnasium"]), (gym_version, pinned)
