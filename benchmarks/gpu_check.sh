#!/usr/bin/env bash
# The mujoco_warp backend on a CUDA machine, in under 8 minutes: install the gpu extra, run its equality tests on
# the GPU (MuJoCo Warp on cuda against MuJoCo C), then print the throughput table of HalfCheetah, Swimmer and
# HumanoidStandup at N = 200, 2,000 and 20,000.
#
#     bash benchmarks/gpu_check.sh            # from the repository root, in the environment to install into
#
# Assumes a CUDA build of torch is installed (a fresh torch download alone can take longer than the budget).
# Warp compiles each task's kernels on first use (cached in ~/.cache/warp): the tests pay for it, the
# benchmark reuses them. Each stage has its own time limit, so a slow stage cannot eat the others' time.
# Episodes are cut at EPISODE_STEPS (default 100): these tasks never terminate early, so the rate per env
# step is that of 1000-step episodes; set EPISODE_STEPS=1000 for full episodes when time allows.
set -u
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python}
EPISODE_STEPS=${EPISODE_STEPS:-100}
POPULATIONS=${POPULATIONS:-200,2000,20000}
start=$(date +%s)
elapsed() { echo "[$(($(date +%s) - start)) s]"; }

echo "== install the gpu extra $(elapsed)"
timeout 90 "$PYTHON" -m pip install -q -e ".[gpu]" pytest || echo "install FAILED or timed out"
"$PYTHON" - <<'EOF'
import mujoco, mujoco_warp, torch, warp
print(f"torch {torch.__version__} (cuda {torch.version.cuda}), mujoco {mujoco.__version__}, "
      f"mujoco_warp {mujoco_warp.__version__}, warp {warp.__version__}")
assert torch.cuda.is_available(), "torch sees no CUDA device: install a CUDA build of torch"
print(torch.cuda.get_device_name(0))
EOF

echo "== equality tests on cuda (MuJoCo Warp vs MuJoCo C; compiles the kernels) $(elapsed)"
SPN_WARP_DEVICE=cuda timeout 180 "$PYTHON" -m pytest tests/test_mujoco_warp.py -m "not slow" -s -p no:cacheprovider \
    || echo "tests FAILED or timed out"

for env_id in HalfCheetah-v5 Swimmer-v5 HumanoidStandup-v5; do
    echo "== throughput $env_id $(elapsed)"
    timeout 65 "$PYTHON" benchmarks/throughput.py --backend mujoco_warp --device cuda --env "$env_id" \
        --populations "$POPULATIONS" --episode-steps "$EPISODE_STEPS" --physics-steps 50 \
        || echo "benchmark of $env_id FAILED or timed out"
done
echo "== done $(elapsed)"
