#!/usr/bin/env bash
# Creates the venv of env.backend=gym_v2: gym 0.21.0 and mujoco-py (free-mujoco-py 2.1.6, which bundles MuJoCo 2.1.0's
# libmujoco210.so) on numpy<2, beside the project's own venv, whose pip and numpy it cannot share.
# Usage: bash scripts/make_gym_v2_env.sh [VENV]   (VENV: $SPN_GYM_V2_VENV, else .venv-gym-v2 in the repository root)
# Needs python3 (3.8 to 3.11) and the Debian packages below (installed here when run as root).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="${1:-${SPN_GYM_V2_VENV:-$root/.venv-gym-v2}}"
packages=(libosmesa6-dev libgl1-mesa-dev libglew-dev patchelf gcc)
missing=()
for p in "${packages[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if ((${#missing[@]})); then
  if [[ $(id -u) == 0 ]]; then
    apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${missing[@]}"
  else
    echo "make_gym_v2_env: install the Debian packages ${missing[*]} first (sudo apt-get install -y ${missing[*]})" >&2
    exit 1
  fi
fi
python3 -m venv "$venv"
pip=("$venv/bin/pip" -q --disable-pip-version-check)
"${pip[@]}" install "pip<24.1"  # pip 24.1 and later reject gym 0.21's metadata
"${pip[@]}" install setuptools==65.5.0 wheel==0.38.4
"${pip[@]}" install "numpy<2" "cython<3" "cffi<2" fasteners==0.15 "glfw<2" "imageio<3"
dl="$(mktemp -d)"
trap 'rm -rf "$dl"' EXIT
# the wheel says Requires-Python <3.11 but runs on 3.11
"${pip[@]}" download --no-deps --ignore-requires-python -d "$dl" free-mujoco-py==2.1.6
"${pip[@]}" install --no-deps --ignore-requires-python "$dl"/free_mujoco_py-2.1.6-py3-none-any.whl
"${pip[@]}" install --no-build-isolation gym==0.21.0
# the first import compiles mujoco-py's Cython extension (1.5 to 2 minutes); the check loads both v2 tasks
"$venv/bin/python" -c "
import gym, mujoco_py
for task in ('HalfCheetah-v2', 'Swimmer-v2'):
    gym.make(task).reset()
print('gym', gym.__version__, 'mujoco-py', mujoco_py.__version__, 'MuJoCo', mujoco_py.functions.mj_version())
"
echo "make_gym_v2_env: $venv is ready (env.backend=gym_v2 finds it there, or at \$SPN_GYM_V2_VENV)"
