#!/usr/bin/env bash
# Creates (or refreshes) .venv-ray, the environment of the Ray tests (tests/ray) and of the
# RLlib example: Ray with RLlib at the range the package's `ray` extra pins
# (python/pyproject.toml), and the gymnasium that Ray pins (1.2.2 for Ray 2.60), layered over
# .venv (torch, pytest and the rogue_gym build come from there through a .pth file, so nothing
# is built or downloaded twice). Run scripts/setup-python.sh first. Idempotent.
#
# Downloads about 250 MB (ray, pyarrow, pandas, scipy); takes 1-3 minutes.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
BASE="$ROOT/.venv/bin/python"
if [ ! -x "$BASE" ]; then
    echo "error: .venv is missing; run bash scripts/setup-python.sh first" >&2
    exit 1
fi
# The extra's Ray requirement, written once in python/pyproject.toml.
RAY_REQ=$("$BASE" -c 'import tomllib
deps = tomllib.load(open("python/pyproject.toml", "rb"))["project"]["optional-dependencies"]["ray"]
print(next(d for d in deps if d.startswith("ray")))')

if [ ! -x .venv-ray/bin/python ]; then
    echo "== creating .venv-ray"
    "$(readlink -f .venv/bin/python)" -m venv .venv-ray
fi
VPY="$ROOT/.venv-ray/bin/python"
SITE=$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
BASE_SITE=$("$BASE" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
# Install before layering, so that pip resolves Ray's own pins (gymnasium) in .venv-ray.
rm -f "$SITE/zz_rogue_gym_base_venv.pth"
echo "== pip install $RAY_REQ (into .venv-ray)"
for attempt in 1 2 3; do
    if "$VPY" -m pip install -q --disable-pip-version-check --retries 10 --timeout 60 "$RAY_REQ"; then
        break
    fi
    if [ "$attempt" = 3 ]; then
        echo "error: pip install $RAY_REQ failed 3 times; check the network or the package index" >&2
        exit 1
    fi
    echo "== pip install failed (attempt $attempt of 3); retrying in $((attempt * 10)) s" >&2
    sleep $((attempt * 10))
done
# .venv's packages come after .venv-ray's own: Ray's gymnasium wins, torch and rogue_gym are
# found in .venv.
echo "import site; site.addsitedir('$BASE_SITE')" >"$SITE/zz_rogue_gym_base_venv.pth"
"$VPY" -c "import ray, gymnasium, torch, rogue_gym
print('ray', ray.__version__, 'gymnasium', gymnasium.__version__, 'torch', torch.__version__, 'rogue_gym', rogue_gym.__version__)"
