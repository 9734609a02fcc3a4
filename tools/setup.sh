#!/usr/bin/env bash
# Installs every Debian 12 package weft's build, tests, benchmarks and tools need.
# Run as root (or with sudo available). Idempotent: prints nothing when all is there.
set -euo pipefail

packages=(
  g++ cmake make pkg-config        # toolchain (C++20, CMake >= 3.25)
  libeigen3-dev                    # Eigen 3.4: SoA storage and vector expressions
  libtbb-dev                       # oneTBB: task_arena + parallel_for
  libgtest-dev libgmock-dev        # GoogleTest
  libbenchmark-dev                 # Google Benchmark
  libcli11-dev                     # CLI11: command-line parsing for `weft`
  nlohmann-json3-dev               # JSON output of `weft run --json`
  libassimp-dev                    # assimp: mesh import (OBJ, 3DS, ...) for weft::io
  libtinygltf-dev                  # tinygltf (its header): glTF frames of `weft run --format gltf`, weft::io
  libboost-dev                     # Boost.Odeint (header-only): cross-check of rk4/rk45 (tests), BM_Peer_Odeint_Rk4 (bench)
  python3-matplotlib               # plots of `weft study` (run with /usr/bin/python3)
  libosmesa6-dev libpng-dev        # `weft render`: Mesa's offscreen OpenGL (llvmpipe, no display or GPU) and PNG files
  libglfw3-dev                     # `weft view`: a window with an OpenGL 3.3 core context
  xvfb xauth                       # `weft view`'s test under a virtual X display (xvfb-run)
  openmpi-bin libopenmpi-dev       # OpenMPI: `mpirun -np N weft study` spreads the sweep over ranks (docs/distributed.md); optional at configure time
  clang-14 libclang-rt-14-dev      # tools/fuzz.sh: clang++-14 and its libFuzzer runtime (-fsanitize=fuzzer)
)

# Peers, optional (WEFT_PEERS=1 bash tools/setup.sh): weft_bench builds BM_Peer_Embree_*
# when Embree is found, BM_Peer_Bullet_Pile / BM_Peer_Bullet_Cloth when Bullet is and
# BM_Peer_Cholmod_* when CHOLMOD (SuiteSparse) is (docs/benchmarks.md).
if [ "${WEFT_PEERS:-0}" = "1" ]; then
  packages+=(libembree-dev libbullet-dev libsuitesparse-dev)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "weft setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "weft setup: done"
