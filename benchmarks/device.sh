#!/usr/bin/env bash
# Evidence on a many-core machine with a GPU, in one script of at most 9 minutes on 16 cores:
#   1. multicore scaling of sync step() from 1 to 16 workers (native game, CartPole,
#      HalfCheetah), as efficiency against linear, and the model behind it: the caller's own
#      time per call against the batch size, projected to 16 workers (benchmarks/scaling.py);
#   2. the async head-to-head with TorchRL's AsyncEnvPool and gymnasium's AsyncVectorEnv on
#      TorchRL's two workloads, at every core (benchmarks/async_pools.py);
#   3. the PPO trainer's frames/s on the GPU (python -m rogue_gym.train, in its own layout:
#      two workers, each half of the envs stepping while the policy acts on the other), or on
#      the CPU where there is none;
#   4. PettingZoo envs as rows beside SuperSuit and a plain loop (benchmarks/multi_agent.py).
# Results go to benchmarks/results/device/ (DEVICE_OUT overrides). A part whose packages are
# missing (mujoco, torchrl) is left out with a message; a part that fails fails the script.
#
#   bash benchmarks/device.sh            # the full run (a 16-core machine)
#   bash benchmarks/device.sh --quick    # a smoke run of every part (CI, any machine)
#   DEVICE_PARTS="1 3" bash benchmarks/device.sh   # some parts only
set -euo pipefail
cd "$(dirname "$0")/.."
quick=()
if [[ "${1:-}" == "--quick" ]]; then quick=(--quick); fi
parts=" ${DEVICE_PARTS:-1 2 3 4} "
part() { [[ "$parts" == *" $1 "* ]]; }
py=${PYTHON:-python3}
out=${DEVICE_OUT:-benchmarks/results/device}
mkdir -p "$out"
export PYTHONUNBUFFERED=1
t0=$SECONDS
cores=$("$py" -c "import os; print(len(os.sched_getaffinity(0)))")
workers=(1 2 4 8 16)
if ((cores < 16)); then workers=(1 2); fi

echo "== machine: $cores cores; $(uname -m)"
"$py" - <<'EOF' | tee "$out/machine.txt"
import platform, sys
print("python", sys.version.split()[0], platform.platform())
try:
    import torch
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none"
    print("torch", torch.__version__, "gpu", gpu)
except ImportError:
    print("torch missing")
EOF

if part 1; then
    echo "== 1. scaling ($((SECONDS - t0)) s)"
    timeout 300 "$py" benchmarks/scaling.py --workers "${workers[@]}" --seconds 3 --out "$out" \
        ${quick[@]+"${quick[@]}"}
    if ((${#quick[@]})); then model=(--quick); else model=(--seconds 1 --reps 2); fi
    timeout 300 "$py" benchmarks/scaling.py --model "${model[@]}" --out "$out"
fi

if part 2; then
    echo "== 2. async head-to-head ($((SECONDS - t0)) s)"
    # Quick: the dispatch workload only (slow_reset's 32-worker pools take long to start).
    if ((${#quick[@]})); then pools=(--quick --workloads dispatch); else pools=(); fi
    timeout 300 "$py" benchmarks/async_pools.py --reps 1 --seconds 4 --out "$out" \
        ${pools[@]+"${pools[@]}"}
fi

if part 3; then
echo "== 3. trainer ($((SECONDS - t0)) s)"
device=$("$py" -c "import torch; print('cuda' if torch.cuda.is_available() else 'cpu')")
# Quick: one update (32 envs x 125 steps, the paper layout).
frames=$([[ ${#quick[@]} -gt 0 ]] && echo 4000 || echo 120000)
run=$(mktemp -d)
trap 'rm -rf "$run"' EXIT
timeout 240 "$py" -m rogue_gym.train --device "$device" --frames "$frames" \
    --eval-every 0 --eval-seeds 1 --eval-episodes 1 \
    --random-episodes 1 --checkpoint-every 1000000000 --out "$run/train" >"$run/train.log" 2>&1 ||
    { tail -20 "$run/train.log"; exit 1; }
"$py" - "$run/train/progress.csv" "$device" "$out" <<'EOF'
import csv, json, sys
rows = list(csv.DictReader(open(sys.argv[1])))
fps = [float(r["fps"]) for r in rows if r.get("fps")]
result = {"device": sys.argv[2], "updates": len(rows), "fps_last": fps[-1], "fps_all": fps}
print(f"trainer on {sys.argv[2]}: {fps[-1]:,.0f} frames/s at the last of {len(rows)} updates")
json.dump(result, open(f"{sys.argv[3]}/train.json", "w"), indent=1)
EOF
fi

if part 4; then
echo "== 4. many agents ($((SECONDS - t0)) s)"
if "$py" -c "import pettingzoo, mpe2" 2>/dev/null; then
    if ((${#quick[@]})); then ma=(--quick --envs simple_spread); else ma=(--num-envs 64 --reps 1); fi
    timeout 300 "$py" benchmarks/multi_agent.py --workers "$((cores < 16 ? 2 : 16))" \
        --out "$out" "${ma[@]}"
else
    echo "pettingzoo or mpe2 missing: part 4 left out"
fi
fi

echo "== done in $((SECONDS - t0)) s; results in $out"
