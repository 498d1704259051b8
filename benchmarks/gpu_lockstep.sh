#!/usr/bin/env bash
# Issue 48's GPU measurement in under 8 minutes on one GPU: the lockstep benchmark (benchmarks/lockstep.py) of
# HalfCheetah, Swimmer and HumanoidStandup on the mujoco_warp backend at N = 200 and R = 1, 7, 10 and 66 runs
# (300, 2,100, 3,000 and 19,800 slots; R = 10 is the paper's 10 seeds in one batch), with torch's profile of 20 env steps of HalfCheetah's device loop at 19,800 slots.
#
#     bash benchmarks/gpu_lockstep.sh     # from the repository root; tables also in $OUT/lockstep.md
#
# The wheels that benchmarks/gpu_wheels.sh packed into .whl/part*/ (carried there) are joined and installed first;
# without them, the environment must already hold the gpu extra. Warp compiles each task's kernels on first use
# (cached in ~/.cache/warp), outside the timed generation. Each task has its own time limit (TASK_S), so a slow
# one cannot eat the others' time. Episodes are cut at EPISODE_STEPS (these tasks never end early, so the rate per
# env step is that of 1000-step episodes).
set -u -o pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
ENVS=${ENVS:-"HalfCheetah-v5 Swimmer-v5 HumanoidStandup-v5"}
DEVICE=${DEVICE:-cuda}  # DEVICE=cpu (Warp's CPU backend) with tiny RUNS, POPULATION, EPISODE_STEPS: a dry run here
RUNS=${RUNS:-1,7,10,66}
POPULATION=${POPULATION:-200}
EPISODE_STEPS=${EPISODE_STEPS:-100}
TASK_S=${TASK_S:-110}  # 3 tasks x 110 s + at most 90 s of install: under 8 minutes
TABLES=${OUT:-/tmp}/lockstep.md
mkdir -p "$(dirname "$TABLES")"
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH}
start=$(date +%s)
elapsed() { echo "[$(($(date +%s) - start)) s]"; }

if compgen -G ".whl/part*/wheels.tar.*" >/dev/null; then
    echo "== install the carried wheels $(elapsed)"
    wheels=$(mktemp -d) site=$(mktemp -d)
    cat .whl/part*/wheels.tar.* | tar -xf - -C "$wheels"
    timeout 90 "$PYTHON" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target "$site" "$wheels"/*.whl || echo "install FAILED or timed out"
    export PYTHONPATH=$site:$PYTHONPATH
fi
DEVICE=$DEVICE "$PYTHON" - <<'PY' || exit 1
import os

import mujoco, mujoco_warp, torch, torchrl, warp

print(f"torch {torch.__version__} (cuda {torch.version.cuda}), torchrl {torchrl.__version__}, "
      f"mujoco {mujoco.__version__}, mujoco_warp {mujoco_warp.__version__}, warp {warp.__version__}")
if os.environ["DEVICE"].startswith("cuda"):
    assert torch.cuda.is_available(), "torch sees no CUDA device"
    print(torch.cuda.get_device_name(0))
PY

: >"$TABLES"
for env_id in $ENVS; do
    echo "== lockstep $env_id $(elapsed)"
    profile=()
    [ "$env_id" = HalfCheetah-v5 ] && profile=(--profile 20)
    timeout "$TASK_S" "$PYTHON" benchmarks/lockstep.py --backend mujoco_warp --device "$DEVICE" --env "$env_id" \
        --runs "$RUNS" --population "$POPULATION" --episode-steps "$EPISODE_STEPS" --physics-steps 50 "${profile[@]}" \
        | tee -a "$TABLES" || echo "lockstep $env_id FAILED or timed out" | tee -a "$TABLES"
done
echo "== done $(elapsed)"
