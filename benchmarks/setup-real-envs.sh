#!/usr/bin/env bash
# Creates .venv-bench, the environment of benchmarks/real_envs.py: the third-party envs (ale-py
# with its ROMs, NLE, MuJoCo, MiniGrid, Crafter) and the C++ pools (EnvPool, ale-py's vector
# env), kept out of the test set-up's .venv because NLE pins gymnasium 1.2.0.
#
# rogue_gym itself, SB3 (with torch) and matplotlib are borrowed from .venv, which
# scripts/setup-python.sh makes: a .pth file puts the package's source folder (with the built
# extension) and .venv's site-packages after .venv-bench's own, so the envs' pins win.
# Downloads about 150 MB; 1-3 minutes. Idempotent and non-interactive.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c "import rogue_gym._native" 2>/dev/null; then
    echo "error: run 'bash scripts/setup-python.sh' first (.venv with the built extension)" >&2
    exit 1
fi
PY="${PYTHON:-python3}"
[ -x .venv-bench/bin/python ] || "$PY" -m venv .venv-bench
VPY="$ROOT/.venv-bench/bin/python"
"$VPY" -m pip install -q --disable-pip-version-check --retries 10 --timeout 60 \
    "gymnasium==1.2.0" cloudpickle numpy opencv-python-headless "ale-py>=0.10" mujoco minigrid nle crafter envpool py-spy
SITE=$("$VPY" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
DEV_SITE=$(.venv/bin/python -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
printf '%s\n%s\n' "$ROOT/python" "$DEV_SITE" > "$SITE/zz-rogue-gym-dev.pth"
"$VPY" -c "import rogue_gym, gymnasium, ale_py, nle, mujoco, minigrid, crafter; print('rogue_gym', rogue_gym.__version__, 'gymnasium', gymnasium.__version__, 'ok')"
