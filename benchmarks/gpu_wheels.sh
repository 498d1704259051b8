#!/usr/bin/env bash
# Here, with PyPI reachable: the wheels that the device machine's image lacks (it has torch, numpy and pytest,
# no MuJoCo, MuJoCo Warp, Warp, TorchRL or Hydra), for its CPython 3.12 on x86-64, packed in one tar cut into
# parts of at most 60 MiB (.whl/part00, part01, ...; .whl/ is git-excluded): one call carries at most 64 MiB,
# and Warp's wheel alone is larger. Each device call carries one part; the last runs benchmarks/gpu_lockstep.sh,
# which joins and installs them (notes/issue48.md gives the calls).
#
#     bash benchmarks/gpu_wheels.sh
set -eu
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
PACKAGES=${PACKAGES:-"mujoco==4.0.1 mujoco-core==4.0.1 mujoco-studio==4.0.1 glfw pyopengl mujoco-warp==4.0.0
    warp-lang==1.19.0 torchrl==0.14.1 tensordict==0.14.3 pyvers hoptorch orjson hydra-core==1.3.8 omegaconf==2.3.1
    antlr4-python3-runtime==4.9.3 gymnasium==1.4.0 farama-notifications"}
exclude=$(git rev-parse --git-path info/exclude)
grep -qx '/.whl/' "$exclude" 2>/dev/null || echo '/.whl/' >>"$exclude"
rm -rf .whl
mkdir -p .whl/all
# shellcheck disable=SC2086  # PACKAGES is a list of requirements
"$PYTHON" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 --platform manylinux1_x86_64 -d .whl/all $PACKAGES
tar -cf - -C .whl/all . | split -b 60M -d -a 2 - .whl/wheels.tar.
for chunk in .whl/wheels.tar.*; do
    part=.whl/part${chunk##*.}
    mkdir -p "$part" && mv "$chunk" "$part/"
done
rm -rf .whl/all
du -sh .whl/part*
